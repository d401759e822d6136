"""Any OpenAI-compatible Chat Completions server (OpenAI, Ollama, vLLM, llama.cpp) through the official SDK.

Every request has a timeout and a bounded number of retries, so a dead server costs at most
timeout * (retries + 1) seconds. Errors come back as ModelError with a short, redacted message: the API key never
appears in a log line, an exception text or a repr.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from tb4.extras import MissingExtraError, require_extra

__all__ = [
    "DEFAULT_MODEL",
    "MODEL_ENV",
    "default_model",
    "ModelError",
    "ModelSettings",
    "ModelClient",
    "redact",
    "NO_KEY_PLACEHOLDER",
    "REASONING_FAMILIES",
    "is_reasoning_model",
    "request_options",
    "cut_at_stop",
]

#: Sent as the key to servers that need none (local Ollama / vLLM / llama.cpp) but the SDK insists on one.
NO_KEY_PLACEHOLDER = "no-key-needed"

_KEYLIKE = re.compile(r"(?:sk|rk|pk)-[A-Za-z0-9_\-]{6,}|(?i:bearer)\s+[A-Za-z0-9_\-.=]{6,}")


def redact(text: str, secrets: Iterable[str] = ()) -> str:
    """Replace each secret (and anything that looks like an API key or bearer token) with '***'."""
    out = str(text)
    for secret in secrets:
        if secret and len(secret) >= 4:
            out = out.replace(secret, "***")
    return _KEYLIKE.sub("***", out)


#: The model asked when none is named (ROS parameter `model_name`, `--model-name`, or $TB4_LLM_MODEL).
#: gpt-3.5-turbo, upstream's default, is retired, and gpt-4o-mini is deprecated by OpenAI, which names gpt-6-luna
#: as its replacement; this is the one place the default lives.
DEFAULT_MODEL = "gpt-6-luna"
#: Model families that reason before answering: they take `reasoning_effort` and `max_completion_tokens`, not
#: the sampling parameters (`temperature`, `stop`) older chat models take. "none" asks for a direct answer, which
#: is all a one-line command needs and the cheapest.
REASONING_FAMILIES = ("gpt-6",)
#: Environment variable that changes the default model for every entry point (gpt_node, the tutorial).
MODEL_ENV = "TB4_LLM_MODEL"


def default_model() -> str:
    """$TB4_LLM_MODEL if set, else DEFAULT_MODEL: what gpt_node and the tutorial ask when no model is named."""
    return os.environ.get(MODEL_ENV, "").strip() or DEFAULT_MODEL


class ModelError(RuntimeError):
    """The model could not be asked (network, HTTP status, timeout, bad reply). The message is redacted."""


@dataclass(frozen=True)
class ModelSettings:
    """Where and how to ask. `api_key` empty: taken from OPENAI_API_KEY; none at all is fine with a base_url."""

    model: str = field(default_factory=default_model)
    base_url: str = ""
    api_key: str = field(default="", repr=False)
    timeout: float = 30.0
    max_retries: int = 2
    temperature: float = 0.0
    max_tokens: int = 512
    stop: tuple[str, ...] = ("\n#",)  # a comment after code starts a new, unrequested command

    def __post_init__(self) -> None:
        if not self.timeout > 0:
            raise ValueError("timeout must be positive")
        if not 0 <= self.max_retries <= 10:
            raise ValueError("max_retries must be between 0 and 10")


class ModelClient:
    """Ask a Chat Completions endpoint for one completion, with bounded waiting and redacted errors."""

    def __init__(self, settings: ModelSettings) -> None:
        try:
            require_extra("llm")
        except MissingExtraError as exc:
            raise ModelError(str(exc)) from None
        import openai  # noqa: PLC0415 - only needed when a model backend is used (extra [llm])

        self.settings = settings
        key = settings.api_key or os.environ.get("OPENAI_API_KEY", "")
        if not key and not settings.base_url:
            raise ModelError(
                "no API key: set the openai_api_key parameter or OPENAI_API_KEY, or give a base_url for a local "
                "server (Ollama, vLLM, llama.cpp)"
            )
        self._secrets = tuple(s for s in (key,) if s)
        self._openai = openai
        self._client = openai.OpenAI(
            api_key=key or NO_KEY_PLACEHOLDER,
            base_url=settings.base_url or None,
            timeout=settings.timeout,
            max_retries=settings.max_retries,
        )

    def __repr__(self) -> str:
        where = self.settings.base_url or "api.openai.com"
        return f"ModelClient(model={self.settings.model!r}, base_url={where!r}, api_key=***)"

    @property
    def worst_case_seconds(self) -> float:
        """Upper bound of one complete() call, retries included (plus the SDK's short back-off)."""
        return self.settings.timeout * (self.settings.max_retries + 1) + 8.0 * self.settings.max_retries

    def redact(self, text: str) -> str:
        return redact(text, self._secrets)

    def complete(self, messages: Sequence[dict[str, str]]) -> str:
        """The text of the first choice; ModelError (redacted) on any failure."""
        s = self.settings
        try:
            response = self._client.chat.completions.create(
                model=s.model,
                messages=list(messages),  # type: ignore[arg-type]
                **request_options(s),
            )
        except self._openai.APITimeoutError:
            raise ModelError(
                f"the model server did not answer within {s.timeout:g} s ({s.max_retries} retries)"
            ) from None
        except self._openai.APIConnectionError as exc:
            raise ModelError(self.redact(f"cannot reach the model server: {exc}")) from None
        except self._openai.APIStatusError as exc:
            detail = self.redact(str(getattr(exc, "message", "") or exc))[:300]
            raise ModelError(f"the model server answered HTTP {exc.status_code}: {detail}") from None
        except self._openai.OpenAIError as exc:
            raise ModelError(self.redact(f"model request failed: {type(exc).__name__}: {exc}")[:400]) from None
        try:
            content = response.choices[0].message.content
        except (AttributeError, IndexError, TypeError):
            raise ModelError("the model server sent a reply without a message") from None
        text = str(content or "")
        if "stop" not in request_options(s):  # the server was not asked to stop there: stop here
            text = cut_at_stop(text, s.stop)
        if not text:
            raise ModelError("the model sent an empty reply")
        return text


def is_reasoning_model(model: str) -> bool:
    """Whether `model` (optionally prefixed by a provider, as "openai/gpt-6-luna") is of a reasoning family."""
    name = model.strip().lower().rsplit("/", 1)[-1]
    return name.startswith(REASONING_FAMILIES)


def request_options(settings: ModelSettings) -> dict[str, Any]:
    """The request's generation parameters, in the form the model's family takes."""
    if is_reasoning_model(settings.model):
        return {"reasoning_effort": "none", "max_completion_tokens": settings.max_tokens}
    return {
        "temperature": settings.temperature,
        "max_tokens": settings.max_tokens,
        "stop": list(settings.stop) if settings.stop else None,
    }


def cut_at_stop(text: str, stop: Sequence[str]) -> str:
    """The text up to the first stop sequence: what a server that honours `stop` returns, also for the models
    that do not take it."""
    for sequence in stop:
        if sequence and sequence in text:
            text = text[: text.index(sequence)]
    return text
