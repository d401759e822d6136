"""Who may reach the viewer, as pure functions: Host parsing, loopback names, the policy for each kind of bind."""

from __future__ import annotations

import pytest

from tb4.viewer.access import AccessPolicy, host_name, is_loopback, policy_for


@pytest.mark.parametrize(
    ("header", "name"),
    [
        ("localhost:8765", "localhost"),
        ("LocalHost", "localhost"),
        ("[::1]:8765", "::1"),
        ("[::1]", "::1"),
        ("::1", "::1"),
        ("evil.example.:80", "evil.example"),
        ("", ""),
    ],
)
def test_host_names_are_read_from_every_form_of_host_header(header: str, name: str) -> None:
    assert host_name(header) == name


@pytest.mark.parametrize("host", ["localhost", "127.0.0.1", "127.8.9.10", "::1", "[::1]", "app.localhost"])
def test_loopback_names(host: str) -> None:
    assert is_loopback(host)


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "10.0.0.5", "127.0.0.1.evil.example", "localhost.evil", ""])
def test_not_loopback(host: str) -> None:
    assert not is_loopback(host)


def test_loopback_bind_needs_no_token_and_serves_only_loopback_names() -> None:
    policy = policy_for("127.0.0.1", 8765)
    assert policy.token is None
    assert policy.allows_host("localhost:8765") and policy.allows_host("[::1]:8765")
    assert not policy.allows_host("evil.example:8765") and not policy.allows_host("")


def test_a_bind_beyond_loopback_needs_a_fresh_token_and_serves_its_own_name() -> None:
    first, second = policy_for("192.0.2.7", 8765), policy_for("192.0.2.7", 8765)
    assert first.token and second.token and first.token != second.token
    assert first.allows_host("192.0.2.7:8765") and not first.allows_host("192.0.2.8:8765")
    assert not first.allows_token(None) and not first.allows_token(first.token + "x")
    assert first.allows_token(first.token)


def test_a_wildcard_bind_serves_this_machines_name_with_a_token() -> None:
    import socket

    policy = policy_for("0.0.0.0", 8765, allow_hosts=["proxy.example"])
    assert policy.token is not None
    assert policy.allows_host(socket.gethostname()) and policy.allows_host("proxy.example:443")
    assert not policy.allows_host("evil.example")


def test_the_token_is_read_from_the_query_or_this_ports_cookie() -> None:
    policy = AccessPolicy(frozenset({"localhost"}), "abc", 9000)
    assert policy.token_in(b"token=abc", "") == "abc"
    assert policy.token_in(b"", "other=1; tb4_viewer_token_9000=abc") == "abc"
    assert policy.token_in(b"", "tb4_viewer_token_9001=abc") is None  # another viewer's cookie
