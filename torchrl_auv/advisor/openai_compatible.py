"""``OpenAICompatibleAdvisor``: any OpenAI-compatible chat-completions endpoint as the advisor.

Works with a hosted API, vLLM, Ollama or a llama.cpp server (``llm`` extra: the ``openai``
client; we use it rather than raw HTTP for its timeouts and error types). Temperature
0.5 and top-p 1 by default, as in the paper (GPT-4o).

**Structured output** is asked for in this order, moving on when the server refuses a strategy
(HTTP 4xx/5xx, e.g. llama.cpp's 500 "Input should be 'text' or 'json_object'" for a JSON
schema) or answers something that is not a JSON object:

1. ``json_schema`` response format (strict schema),
2. a forced tool call whose parameters are the schema,
3. ``json_object`` response format (with the schema, which llama.cpp enforces),
4. free text, the first JSON object parsed out of it.

The first strategy that worked is tried first next time. A timeout or a refused connection
ends the consultation at once (the other strategies would meet the same server). On any
failure the advisor returns the current spec with the reason; it never raises for a bad
answer or a dead server, never executes the answer and never uses it as a path.

**The API key** is read from the environment variable named by ``api_key_env`` when a request
is made; it is never stored on the object, put in a decision or logged. A local server that
needs no key gets the placeholder ``"not-needed"``.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import replace
from typing import Any

from torchrl_auv.advisor.decision import AdvisorDecision, validate_answer
from torchrl_auv.advisor.feedback import TrainingFeedback
from torchrl_auv.advisor.prompt import DECISION_SCHEMA, build_messages, json_from_text
from torchrl_auv.objectives import LyapunovSpec

__all__ = ["STRATEGIES", "OpenAICompatibleAdvisor"]

STRATEGIES = ("json_schema", "tool", "json_object", "text")
_TOOL = "set_lyapunov_function"


class OpenAICompatibleAdvisor:
    """Ask a chat model for the Lyapunov form, prior and alpha (module docstring).

    Args:
        base_url: the endpoint, e.g. ``"http://127.0.0.1:8080/v1"``.
        model: the model name the server expects.
        api_key_env: name of the environment variable holding the key (not the key).
        timeout: seconds for a whole consultation (every strategy and retry): the longest the
            advisor can block a training loop.
        max_retries: retries of a request whose connection failed, within ``timeout``.
        temperature, top_p: sampling (paper: 0.5 and 1).
        max_tokens: longest answer.

    Examples:
        >>> advisor = OpenAICompatibleAdvisor("http://127.0.0.1:9/v1", "any", timeout=0.5,
        ...                                   max_retries=0)
        >>> decision = advisor.propose("hold depth", None, LyapunovSpec(form="log"))
        >>> decision.accepted, decision.form, decision.reasons[0].startswith("connection")
        (False, 'log', True)
    """

    def __init__(
        self,
        base_url: str,
        model: str,
        *,
        api_key_env: str = "OPENAI_API_KEY",
        timeout: float = 30.0,
        max_retries: int = 1,
        temperature: float = 0.5,
        top_p: float = 1.0,
        max_tokens: int = 400,
    ) -> None:
        if not isinstance(base_url, str) or not base_url.startswith(("http://", "https://")):
            raise ValueError(f"base_url must be an http(s) URL, got {base_url!r}")
        if not model:
            raise ValueError("model must be a non-empty model name")
        if not api_key_env or not str(api_key_env).replace("_", "").isalnum():
            raise ValueError(f"api_key_env must name an environment variable, got {api_key_env!r}")
        if not timeout > 0:
            raise ValueError(f"timeout must be > 0 seconds, got {timeout}")
        if not (isinstance(max_retries, int) and max_retries >= 0):
            raise ValueError(f"max_retries must be an int >= 0, got {max_retries!r}")
        if not 0 <= temperature <= 2:
            raise ValueError(f"temperature must be in [0, 2], got {temperature}")
        if not 0 < top_p <= 1:
            raise ValueError(f"top_p must be in (0, 1], got {top_p}")
        self.base_url, self.model, self.api_key_env = base_url, model, api_key_env
        self.timeout, self.max_retries = float(timeout), max_retries
        self.temperature, self.top_p, self.max_tokens = temperature, top_p, max_tokens
        self.strategies = list(STRATEGIES)

    def __repr__(self) -> str:  # no key in here: it is never stored
        return (
            f"{type(self).__name__}(base_url={self.base_url!r}, model={self.model!r}, "
            f"api_key_env={self.api_key_env!r})"
        )

    def _client(self):
        try:
            import openai
        except ImportError as err:  # pragma: no cover - the llm extra is in the lock file
            raise ImportError("OpenAICompatibleAdvisor needs the 'llm' extra: openai") from err
        key = os.environ.get(self.api_key_env) or "not-needed"
        # retries are ours (within the consultation's deadline), not the client's
        return openai.OpenAI(
            base_url=self.base_url, api_key=key, timeout=self.timeout, max_retries=0
        )

    def _request(self, client, strategy: str, messages) -> str:
        """One chat completion with ``strategy``; returns the text holding the JSON answer."""
        extra: dict[str, Any] = {}
        if strategy == "json_schema":
            extra["response_format"] = {
                "type": "json_schema",
                "json_schema": {
                    "name": "lyapunov_decision",
                    "schema": DECISION_SCHEMA,
                    "strict": True,
                },
            }
        elif strategy == "tool":
            extra["tools"] = [
                {
                    "type": "function",
                    "function": {
                        "name": _TOOL,
                        "description": "Set the Lyapunov function for training.",
                        "parameters": DECISION_SCHEMA,
                    },
                }
            ]
            extra["tool_choice"] = {"type": "function", "function": {"name": _TOOL}}
        elif strategy == "json_object":
            extra["response_format"] = {"type": "json_object", "schema": DECISION_SCHEMA}
        response = client.chat.completions.create(
            model=self.model,
            messages=messages,
            temperature=self.temperature,
            top_p=self.top_p,
            max_tokens=self.max_tokens,
            **extra,
        )
        message = response.choices[0].message
        if strategy == "tool":
            calls = message.tool_calls or []
            if not calls:
                raise ValueError("no tool call in the answer")
            return calls[0].function.arguments or ""
        return message.content or ""

    def propose(
        self, task: str, feedback: TrainingFeedback | None, current: LyapunovSpec
    ) -> AdvisorDecision:
        import openai

        messages = build_messages(task, feedback, current)
        client = self._client()
        deadline = time.monotonic() + self.timeout  # the whole consultation, all attempts
        reasons: list[str] = []
        raw = ""
        for strategy in list(self.strategies):
            source = f"openai:{self.model}:{strategy}"
            try:
                raw = self._request_within(client, strategy, messages, deadline)
                answer = json.loads(raw) if strategy != "text" else json_from_text(raw)
            except (openai.APITimeoutError, TimeoutError):
                reasons.append(f"timeout after {self.timeout:g} s at {self.base_url} ({strategy})")
                break
            except openai.APIConnectionError as err:
                reasons.append(
                    f"connection to {self.base_url} failed ({strategy}): {type(err).__name__}"
                )
                break
            except openai.APIStatusError as err:
                reasons.append(f"HTTP {err.status_code} for {strategy}: {_short(err.message)}")
                continue
            except (ValueError, TypeError) as err:  # json.JSONDecodeError is a ValueError
                reasons.append(f"malformed answer for {strategy}: {_short(str(err))}")
                continue
            if not isinstance(answer, dict):
                reasons.append(f"answer for {strategy} is not a JSON object")
                continue
            self.strategies.remove(strategy)  # the working strategy goes first next time
            self.strategies.insert(0, strategy)
            decision = validate_answer(answer, current, source, raw=raw[:4000])
            reasons += decision.reasons
            return replace(decision, reasons=tuple(reasons))
        return AdvisorDecision.keep(current, f"openai:{self.model}", *reasons, raw=raw[:4000])

    def _request_within(self, client, strategy: str, messages, deadline: float) -> str:
        """``_request`` with the time left before ``deadline`` (``TimeoutError`` when none is
        left); a refused connection is retried ``max_retries`` times while time is left."""
        import openai

        attempt = 0
        while (remaining := deadline - time.monotonic()) > 0:
            try:
                return self._request(client.with_options(timeout=remaining), strategy, messages)
            except openai.APIConnectionError as err:
                if isinstance(err, openai.APITimeoutError) or attempt == self.max_retries:
                    raise
            time.sleep(min(0.5 * 2**attempt, max(deadline - time.monotonic(), 0)))
            attempt += 1
        raise TimeoutError


def _short(text: str, n: int = 160) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= n else text[: n - 3] + "..."
