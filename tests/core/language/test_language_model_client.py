"""The model backend through the real `openai` SDK against our own scripted server on 127.0.0.1."""

from __future__ import annotations

import logging
import time

import pytest

from tb4.language.commands import ModelBackend
from tb4.language.model_client import ModelClient, ModelError, ModelSettings, redact
from tb4.language.scripted_server import Reply, ScriptedServer

SECRET = "sk-test-THISISASECRETKEY0123456789"


@pytest.fixture(autouse=True)
def _no_env_key(monkeypatch) -> None:
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    monkeypatch.delenv("OPENAI_BASE_URL", raising=False)


def client_for(server: ScriptedServer, **kw) -> ModelClient:
    settings = ModelSettings(model=kw.pop("model", "test-model"), base_url=server.base_url, **kw)
    return ModelClient(settings)


def test_completion_request_is_what_upstream_sends(depot_context) -> None:
    table, _ = depot_context
    with ScriptedServer(["navigator.dock()"]) as server:
        backend = ModelBackend(client_for(server, api_key=SECRET, model="gpt-3.5-turbo"), table)
        answer = backend.program_for("Dock")
    assert answer.program == "navigator.dock()\n"
    request = server.requests[0]
    assert request["path"] == "/v1/chat/completions"
    body = request["body"]
    assert body["model"] == "gpt-3.5-turbo"
    assert body["temperature"] == 0 and body["max_tokens"] == 512
    assert body["messages"][-1]["content"].rstrip().endswith("# Dock")
    auth = {k.lower(): v for k, v in request["headers"].items()}["authorization"]
    assert auth == f"Bearer {SECRET}"  # the key goes to the server it is meant for, and nowhere else


def test_reasoning_models_get_their_own_parameters_and_the_stop_is_applied_here(depot_context) -> None:
    """gpt-6 models (the default's family) reject the sampling parameters: they are asked with reasoning effort
    "none" and max_completion_tokens, and the stop sequence is cut on our side."""
    table, _ = depot_context
    with ScriptedServer(["navigator.dock()\n# and now undock\nnavigator.undock()"]) as server:
        backend = ModelBackend(client_for(server, api_key=SECRET, model="gpt-6-luna"), table)
        answer = backend.program_for("Dock")
    assert answer.program == "navigator.dock()\n"
    body = server.requests[0]["body"]
    assert body["model"] == "gpt-6-luna"
    assert body["reasoning_effort"] == "none" and body["max_completion_tokens"] == 512
    assert not {"temperature", "max_tokens", "stop"} & set(body)


def test_default_model_is_current_and_configurable(monkeypatch) -> None:
    from tb4.language.model_client import DEFAULT_MODEL, default_model, is_reasoning_model

    monkeypatch.delenv("TB4_LLM_MODEL", raising=False)
    assert default_model() == DEFAULT_MODEL == "gpt-6-luna" and is_reasoning_model(DEFAULT_MODEL)
    monkeypatch.setenv("TB4_LLM_MODEL", "llama3.2")
    assert default_model() == "llama3.2" and not is_reasoning_model("llama3.2")
    assert is_reasoning_model("openai/gpt-6-luna") and not is_reasoning_model("gpt-4o-mini")


def test_key_from_environment_and_local_server_without_key(monkeypatch) -> None:
    with ScriptedServer(["navigator.undock()"]) as server:
        monkeypatch.setenv("OPENAI_API_KEY", SECRET)
        assert client_for(server).complete([{"role": "user", "content": "x"}]) == "navigator.undock()"
        monkeypatch.delenv("OPENAI_API_KEY")
        assert client_for(server).complete([{"role": "user", "content": "x"}]) == "navigator.undock()"
    headers = [{k.lower(): v for k, v in r["headers"].items()} for r in server.requests]
    assert headers[0]["authorization"] == f"Bearer {SECRET}"
    assert SECRET not in headers[1]["authorization"]


def test_no_key_and_no_server_is_a_clear_error() -> None:
    with pytest.raises(ModelError, match="no API key"):
        ModelClient(ModelSettings())


def test_retries_are_bounded_and_errors_are_reported() -> None:
    with ScriptedServer([Reply(status=500, error="boom")]) as server:
        client = client_for(server, api_key=SECRET, max_retries=2, timeout=5.0)
        started = time.monotonic()
        with pytest.raises(ModelError, match="HTTP 500") as info:
            client.complete([{"role": "user", "content": "x"}])
        assert time.monotonic() - started < client.worst_case_seconds
    assert len(server.requests) == 3  # one try + two retries, no more
    assert SECRET not in str(info.value)


def test_timeout_is_bounded() -> None:
    with ScriptedServer([Reply(content="navigator.dock()", delay=3.0)]) as server:
        client = client_for(server, api_key=SECRET, max_retries=0, timeout=0.5)
        started = time.monotonic()
        with pytest.raises(ModelError, match="did not answer within"):
            client.complete([{"role": "user", "content": "x"}])
        assert time.monotonic() - started < 3.0


def test_unreachable_server_is_a_clean_error() -> None:
    server = ScriptedServer(["x"])
    url = server.base_url
    server._httpd.server_close()  # the port is now closed: nothing listens
    client = ModelClient(ModelSettings(base_url=url, api_key=SECRET, max_retries=1, timeout=2.0))
    with pytest.raises(ModelError, match="cannot reach") as info:
        client.complete([{"role": "user", "content": "x"}])
    assert SECRET not in str(info.value)


def test_key_echoed_by_the_server_is_redacted(caplog) -> None:
    caplog.set_level(logging.DEBUG)
    with ScriptedServer([Reply(status=401, error=f"Incorrect API key provided: {SECRET}")]) as server:
        client = client_for(server, api_key=SECRET, max_retries=0)
        with pytest.raises(ModelError) as info:
            client.complete([{"role": "user", "content": "x"}])
    assert "HTTP 401" in str(info.value)
    assert SECRET not in str(info.value) and "***" in str(info.value)
    assert SECRET not in repr(client) and SECRET not in repr(client.settings)
    assert SECRET not in caplog.text


def test_empty_reply_is_an_error() -> None:
    with ScriptedServer([""]) as server, pytest.raises(ModelError, match="empty"):
        client_for(server, api_key=SECRET).complete([{"role": "user", "content": "x"}])


def test_redact_covers_key_like_tokens() -> None:
    text = f"key {SECRET} header Bearer abcdefghijkl and sk-other1234567 ok"
    out = redact(text, [SECRET])
    assert SECRET not in out and "abcdefghijkl" not in out and "sk-other1234567" not in out
    assert out == "key *** header *** and *** ok"


def test_model_backend_reports_errors_as_answers(depot_context) -> None:
    table, _ = depot_context
    with ScriptedServer([Reply(status=503, error="overloaded")]) as server:
        backend = ModelBackend(client_for(server, api_key=SECRET, max_retries=0), table)
        answer = backend.program_for("Dock")
    assert answer.program is None and answer.message.startswith("model error") and "503" in answer.message
