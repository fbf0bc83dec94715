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

from torchrl_auv.advisor import AdvisorTrigger, OpenAICompatibleAdvisor, openai_compatible
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


def test_success_uses_the_json_schema_and_applies_the_decision(
    chat_server, tmp_path, caplog, secret_key
):
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


def test_500_then_tool_call_fallback(chat_server, tmp_path, caplog, secret_key):
    chat_server.replies = [
        chat_server.reply(500, LLAMA_500),
        chat_server.reply(tool_arguments=GOOD),
    ]
    decision, loss, record = consult(chat_server.base_url, tmp_path, caplog)
    assert decision.accepted and decision.source.endswith(":tool")
    assert "HTTP 500 for json_schema" in decision.reasons[0] and LLAMA_500 in decision.reasons[0]
    assert loss.spec.form == "squared" and record["reasons"] == list(decision.reasons)
    assert [strategy_of(r["body"]) for r in chat_server.requests] == ["json_schema", "tool"]


def strategy_of(body):
    """Which structured-output strategy a request body asks for (OpenAI wire format)."""
    if "tools" in body or "tool_choice" in body:
        assert body["tool_choice"]["function"]["name"] == body["tools"][0]["function"]["name"]
        return "tool"
    return body.get("response_format", {}).get("type", "text")


FIRST_CONSULTATION = {  # the replies after which `strategy` is the first that worked
    "tool": [(500, LLAMA_500, None), (200, None, GOOD)],
    "json_object": [(500, LLAMA_500, None), (400, "no tools", None), (200, GOOD, None)],
    "text": [
        (500, LLAMA_500, None),
        (400, "no tools", None),
        (200, "not json", None),
        (200, f"Sure: {GOOD}", None),
    ],
}


@pytest.mark.parametrize("strategy", list(FIRST_CONSULTATION))
def test_the_working_strategy_goes_first_next_time(chat_server, secret_key, strategy):
    """Second consultation against a server that takes every strategy: its first (and only)
    request uses the strategy that worked the first time, not json_schema."""
    advisor = OpenAICompatibleAdvisor(
        chat_server.base_url,
        "fake-model",
        api_key_env="TEST_ADVISOR_KEY",
        timeout=10.0,
        max_retries=0,
    )
    chat_server.replies = [
        chat_server.reply(status, content, tool_arguments=tool)
        for status, content, tool in FIRST_CONSULTATION[strategy]
    ]
    first = advisor.propose("hold depth", None, CURRENT)
    n = len(FIRST_CONSULTATION[strategy])
    assert first.accepted and first.source == f"openai:fake-model:{strategy}"
    assert len(chat_server.requests) == n
    assert strategy_of(chat_server.requests[0]["body"]) == "json_schema"

    def any_strategy(body):  # a server that accepts every strategy
        if "tools" in body:
            return chat_server.reply(tool_arguments=GOOD)(body)
        return chat_server.reply(content=GOOD)(body)

    chat_server.replies = [any_strategy]
    second = advisor.propose("hold depth", None, CURRENT)
    assert second.accepted and second.source == f"openai:fake-model:{strategy}"
    assert second.reasons == ()  # nothing failed: the remembered strategy was tried first
    assert len(chat_server.requests) == n + 1
    assert strategy_of(chat_server.requests[n]["body"]) == strategy


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


def test_timeout_keeps_the_spec_and_ends_the_consultation(
    chat_server, tmp_path, caplog, secret_key
):
    """A server that would answer after 30 s, a 0.5 s timeout: one request, the spec kept, back
    well before the server would have answered (a bound no loaded machine comes near)."""
    chat_server.replies = [chat_server.reply(content=GOOD, delay=30.0)]
    start = time.perf_counter()
    decision, loss, record = consult(chat_server.base_url, tmp_path, caplog, timeout=0.5)
    assert time.perf_counter() - start < 15.0 and record["latency_s"] < 15.0
    assert len(chat_server.requests) == 1  # a timeout ends the consultation at once
    assert not decision.accepted and loss.spec == CURRENT
    assert record["reasons"] == [f"timeout after 0.5 s at {chat_server.base_url} (json_schema)"]


def test_the_timeout_bounds_the_whole_consultation(chat_server, tmp_path, caplog, secret_key):
    """A 500 after 0.5 s, then a fallback that answers after 2.6 s, within a 3 s timeout.

    One deadline for the consultation leaves the fallback at most 3 - 0.5 = 2.5 s, less than the
    server's 2.6 s, so it must time out however slow the machine; a fresh 3 s per request would
    have let it answer."""
    chat_server.replies = [
        chat_server.reply(500, LLAMA_500, delay=0.5),
        chat_server.reply(content=GOOD, delay=2.6),
    ]
    decision, loss, record = consult(chat_server.base_url, tmp_path, caplog, timeout=3.0)
    assert len(chat_server.requests) == 2
    assert [strategy_of(r["body"]) for r in chat_server.requests] == ["json_schema", "tool"]
    assert record["reasons"][0].startswith("HTTP 500 for json_schema")
    assert record["reasons"][1:] == [f"timeout after 3 s at {chat_server.base_url} (tool)"]
    assert not decision.accepted and loss.spec == CURRENT and record["latency_s"] < 15.0


class _VirtualClock:
    """Stands in for ``time`` in the advisor module: ``sleep`` advances the clock at once."""

    def __init__(self):
        self.offset, self.sleeps = 0.0, []

    def monotonic(self):
        return time.monotonic() + self.offset

    def sleep(self, seconds):
        self.sleeps.append(seconds)
        self.offset += seconds


def test_connection_refused_keeps_the_spec(tmp_path, caplog, secret_key, monkeypatch):
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/v1"
    decision, loss, record = consult(url, tmp_path, caplog)
    assert not decision.accepted and loss.spec == CURRENT
    assert record["reasons"][0].startswith(f"connection to {url} failed")
    # said on the console (the trigger's logger), with the endpoint
    warnings = [r for r in caplog.records if r.levelname == "WARNING" and url in r.getMessage()]
    assert len(warnings) == 1 and "kept the Lyapunov spec" in warnings[0].getMessage()

    clock = _VirtualClock()  # back-offs cost no wall time and no machine load can stretch them
    monkeypatch.setattr(openai_compatible, "time", clock)

    def attempts_of(advisor):
        calls = []
        request = advisor._request
        monkeypatch.setattr(advisor, "_request", lambda *a: calls.append(1) or request(*a))
        return calls

    # max_retries retries, each after a back-off, all within the timeout
    retrying = OpenAICompatibleAdvisor(url, "m", timeout=30.0, max_retries=2)
    calls = attempts_of(retrying)
    decision = retrying.propose("x", None, CURRENT)
    assert not decision.accepted and decision.reasons[0].startswith(f"connection to {url} failed")
    assert len(calls) == 1 + 2 and len(clock.sleeps) == 2
    assert all(s > 0 for s in clock.sleeps) and sum(clock.sleeps) <= 30.0
    # a short timeout ends the retries early: never sleeps past the deadline
    clock.sleeps.clear()
    hurried = OpenAICompatibleAdvisor(url, "m", timeout=1.0, max_retries=50)
    calls = attempts_of(hurried)
    decision = hurried.propose("x", None, CURRENT)
    assert not decision.accepted and decision.form == CURRENT.form
    assert decision.reasons[0].startswith((f"timeout after 1 s at {url}", f"connection to {url}"))
    assert 1 <= len(calls) < 51 and sum(clock.sleeps) <= 1.0 + 1e-9


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
