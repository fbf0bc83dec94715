"""OpenAICompatibleAdvisor against a real HTTP server on 127.0.0.1 (tests/advisor/conftest.py).

Every path ends with a valid spec and a recorded reason; the API key reaches the server (as a
bearer token) but never a decision, the decision log or the Python log.
"""

from __future__ import annotations

import json
import logging
import socket
import time

import pytest

from torchrl_auv.advisor import AdvisorTrigger, OpenAICompatibleAdvisor
from torchrl_auv.objectives import LyapunovSpec

SECRET = "sk-test-DO-NOT-LOG-4242"
CURRENT = LyapunovSpec(form="softplus", alpha=0.1)
GOOD = json.dumps({"form": "squared", "prior": None, "alpha": 0.25, "rationale": "oscillating"})
LLAMA_500 = "Input should be 'text' or 'json_object'"


class _Loss:
    def __init__(self):
        self.spec = CURRENT

    def set_lyapunov_spec(self, spec):
        self.spec = spec


@pytest.fixture
def secret_key(monkeypatch):
    monkeypatch.setenv("TEST_ADVISOR_KEY", SECRET)
    return SECRET


def consult(server_url, tmp_path, caplog, **kwargs):
    """One consultation through the trigger; returns (decision, loss, log text)."""
    advisor = OpenAICompatibleAdvisor(
        server_url,
        "fake-model",
        api_key_env="TEST_ADVISOR_KEY",
        timeout=kwargs.pop("timeout", 5.0),
        max_retries=0,
    )
    loss = _Loss()
    trigger = AdvisorTrigger(advisor, "hold depth", log_path=tmp_path / "advisor.jsonl")
    with caplog.at_level(logging.DEBUG):
        decision = trigger.step(0, None, loss)
    log = (tmp_path / "advisor.jsonl").read_text()
    assert SECRET not in log and SECRET not in caplog.text and SECRET not in repr(advisor)
    assert isinstance(loss.spec, LyapunovSpec)
    return decision, loss, json.loads(log.splitlines()[-1])


def test_success_uses_the_json_schema_and_applies_the_decision(chat_server, tmp_path, caplog,
                                                               secret_key):  # fmt: skip
    chat_server.replies = [chat_server.reply(content=GOOD)]
    decision, loss, record = consult(chat_server.base_url, tmp_path, caplog)
    assert decision.accepted and decision.source == "openai:fake-model:json_schema"
    assert (loss.spec.form, loss.spec.alpha) == ("squared", 0.25) and record["applied"]
    request = chat_server.requests[0]
    assert request["path"] == "/v1/chat/completions"
    assert request["headers"]["authorization"] == f"Bearer {SECRET}"
    body = request["body"]
    assert body["temperature"] == 0.5 and body["top_p"] == 1.0
    assert body["response_format"]["type"] == "json_schema"
    assert "squared" in body["messages"][1]["content"]  # the form library is in the prompt


def test_500_then_tool_call_fallback_and_the_working_strategy_goes_first(
    chat_server, tmp_path, caplog, secret_key
):
    chat_server.replies = [
        chat_server.reply(500, LLAMA_500),
        chat_server.reply(tool_arguments=GOOD),
    ]
    decision, loss, record = consult(chat_server.base_url, tmp_path, caplog)
    assert decision.accepted and decision.source.endswith(":tool")
    assert "HTTP 500 for json_schema" in decision.reasons[0] and LLAMA_500 in decision.reasons[0]
    assert loss.spec.form == "squared" and record["reasons"] == list(decision.reasons)
    assert chat_server.requests[1]["body"]["tool_choice"]["function"]["name"]


def test_json_object_then_text_fallbacks(chat_server, tmp_path, caplog, secret_key):
    chat_server.replies = [
        chat_server.reply(500, LLAMA_500),
        chat_server.reply(400, "no tools"),
        chat_server.reply(content="not json"),
        chat_server.reply(content=f"Here you go:\n```json\n{GOOD}\n```"),
    ]
    decision, loss, _ = consult(chat_server.base_url, tmp_path, caplog)
    assert decision.accepted and decision.source.endswith(":text") and loss.spec.alpha == 0.25
    kinds = [r["body"].get("response_format", {}).get("type") for r in chat_server.requests]
    assert kinds == ["json_schema", None, "json_object", None]
    assert "tools" in chat_server.requests[1]["body"]


def test_malformed_json_everywhere_keeps_the_spec(chat_server, tmp_path, caplog, secret_key):
    chat_server.replies = [chat_server.reply(content='{"form": "log", "alpha": ')]
    decision, loss, record = consult(chat_server.base_url, tmp_path, caplog)
    assert not decision.accepted and loss.spec == CURRENT and not record["applied"]
    assert sum("malformed" in r for r in decision.reasons) == 4  # every strategy tried


def test_alpha_out_of_range_is_snapped(chat_server, tmp_path, caplog, secret_key):
    answer = json.dumps({"form": "log", "prior": "velocity", "alpha": 7, "rationale": "x"})
    chat_server.replies = [chat_server.reply(content=answer)]
    decision, loss, _ = consult(chat_server.base_url, tmp_path, caplog)
    assert decision.accepted and loss.spec.alpha == 0.5 and loss.spec.prior == "velocity"
    assert "alpha 7 snapped into [0.05, 0.5]" in decision.reasons


def test_unknown_form_is_rejected(chat_server, tmp_path, caplog, secret_key):
    answer = json.dumps({"form": "rm -rf /", "prior": None, "alpha": 0.2, "rationale": "x"})
    chat_server.replies = [chat_server.reply(content=answer)]
    decision, loss, record = consult(chat_server.base_url, tmp_path, caplog)
    assert not decision.accepted and loss.spec == CURRENT
    assert "unknown form" in record["reasons"][0] and record["raw_answer"] == answer


def test_timeout_keeps_the_spec_within_the_timeout(chat_server, tmp_path, caplog, secret_key):
    chat_server.replies = [chat_server.reply(content=GOOD, delay=3.0)]
    start = time.perf_counter()
    decision, loss, record = consult(chat_server.base_url, tmp_path, caplog, timeout=0.5)
    assert time.perf_counter() - start < 2.0 and len(chat_server.requests) == 1
    assert not decision.accepted and loss.spec == CURRENT
    assert record["reasons"][0].startswith("timeout after 0.5 s") and record["latency_s"] < 2.0


def test_the_timeout_bounds_the_whole_consultation(chat_server, tmp_path, caplog, secret_key):
    """A quick 500 and then a slow fallback: the two requests share one deadline."""
    chat_server.replies = [
        chat_server.reply(500, LLAMA_500),
        chat_server.reply(content=GOOD, delay=3.0),
    ]
    start = time.perf_counter()
    _, loss, record = consult(chat_server.base_url, tmp_path, caplog, timeout=1.0)
    assert time.perf_counter() - start < 1.8 and len(chat_server.requests) == 2
    assert record["reasons"][0].startswith("HTTP 500") and record["reasons"][1].startswith(
        "timeout"
    )
    assert loss.spec == CURRENT


def test_connection_refused_keeps_the_spec(tmp_path, caplog, secret_key):
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    decision, loss, record = consult(f"http://127.0.0.1:{port}/v1", tmp_path, caplog)
    assert not decision.accepted and loss.spec == CURRENT
    assert record["reasons"][0].startswith("connection failed")
    retrying = OpenAICompatibleAdvisor(
        f"http://127.0.0.1:{port}/v1", "m", timeout=5.0, max_retries=2
    )
    start = time.perf_counter()
    assert not retrying.propose("x", None, CURRENT).accepted
    assert 1.4 < time.perf_counter() - start < 5.0  # two back-offs (0.5 s, 1 s) within the deadline


def test_bad_arguments_name_the_argument():
    for kwargs, name in [
        ({"base_url": "ftp://x"}, "base_url"),
        ({"model": ""}, "model"),
        ({"timeout": 0}, "timeout"),
        ({"api_key_env": "sk-123 key"}, "api_key_env"),
        ({"temperature": 3}, "temperature"),
        ({"top_p": 0}, "top_p"),
        ({"max_retries": -1}, "max_retries"),
    ]:
        args = {"base_url": "http://127.0.0.1:1/v1", "model": "m", **kwargs}
        with pytest.raises(ValueError, match=name):
            OpenAICompatibleAdvisor(args.pop("base_url"), args.pop("model"), **args)
