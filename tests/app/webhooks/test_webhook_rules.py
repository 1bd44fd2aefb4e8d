"""The rules of webhooks that need no server: which URLs may be registered (SSRF), the
Standard Webhooks signature (checked by the ``standardwebhooks`` package), and the backoff.

No test here resolves a name in DNS or opens a connection: names are looked up by a stub.
"""

from __future__ import annotations

import ipaddress
import json
import random
import time
from datetime import timedelta

import pytest
from standardwebhooks import Webhook as Verifier

from app.webhooks import signing
from app.webhooks.delivery import Policy
from app.webhooks.targets import address_kind, check_url
from engine.errors import InputError

ONLY_PUBLIC = "webhooks may only go to public addresses"
ONLY_LOOPBACK = "webhooks may only go to loopback (ACV_WEBHOOK_TARGETS=loopback) addresses"
NOT_HTTPS = (
    "a webhook URL must be https (http only to a loopback address in tests, "
    "ACV_WEBHOOK_TARGETS=loopback)"
)


def no_lookup(host: str, port: int) -> list:
    raise AssertionError(f"{host} was looked up")


def resolves_to(*addresses: str):
    return lambda host, port: [ipaddress.ip_address(a) for a in addresses]


@pytest.mark.parametrize(
    ("url", "refusal"),
    [
        ("https://10.0.0.1/hook", f"10.0.0.1 is a private address: {ONLY_PUBLIC}"),
        ("https://192.168.1.1", f"192.168.1.1 is a private address: {ONLY_PUBLIC}"),
        ("https://172.16.0.5/x", f"172.16.0.5 is a private address: {ONLY_PUBLIC}"),
        (
            "https://169.254.169.254/latest/meta-data",
            f"169.254.169.254 is a link-local address: {ONLY_PUBLIC}",
        ),
        ("https://127.0.0.1:8443/", f"127.0.0.1 is a loopback address: {ONLY_PUBLIC}"),
        ("https://[::1]/", f"::1 is a loopback address: {ONLY_PUBLIC}"),
        ("https://[::ffff:10.0.0.1]/", f"::ffff:10.0.0.1 is a private address: {ONLY_PUBLIC}"),
        ("https://[fd00::1]/", f"fd00::1 is a private address: {ONLY_PUBLIC}"),
        ("https://[2002:a00:1::]/", f"2002:a00:1:: is a private address: {ONLY_PUBLIC}"),
        ("https://0.0.0.0/", f"0.0.0.0 is an unspecified address: {ONLY_PUBLIC}"),
        ("https://224.0.0.1/", f"224.0.0.1 is a multicast address: {ONLY_PUBLIC}"),
        ("https://100.64.0.1/", f"100.64.0.1 is a special-purpose address: {ONLY_PUBLIC}"),
        ("http://example.com/hook", NOT_HTTPS),
        ("http://8.8.8.8/hook", NOT_HTTPS),
        ("ftp://example.com/", "a webhook URL must be https://host/path"),
        ("https:///nohost", "a webhook URL must be https://host/path"),
        (
            "https://user:pw@example.com/",
            "a webhook URL must not hold credentials (user:password@)",
        ),
        ("https://example.com:99999/", "the webhook URL's port must be in 1..65535"),
        ("https://exa mple.com/", "a webhook URL is at most 2000 printable characters"),
    ],
)
def test_a_refused_url_is_refused_before_any_lookup(url: str, refusal: str) -> None:
    with pytest.raises(InputError) as refused:
        check_url(url, targets="public", resolve=no_lookup)
    assert str(refused.value) == refusal


def test_a_name_is_refused_when_any_of_its_addresses_is_private() -> None:
    """DNS rebinding at registration: one private address among public ones is enough."""
    with pytest.raises(InputError) as refused:
        check_url(
            "https://hooks.example.org/x",
            targets="public",
            resolve=resolves_to("93.184.216.34", "10.1.2.3"),
        )
    assert str(refused.value) == (
        f"hooks.example.org (10.1.2.3) is a private address: {ONLY_PUBLIC}"
    )


def test_a_public_https_url_is_taken_and_pinned_to_the_address_checked() -> None:
    target = check_url(
        "https://hooks.example.org:8443/in?x=1",
        targets="public",
        resolve=resolves_to("93.184.216.34"),
    )
    assert target.pinned_url == "https://93.184.216.34:8443/in?x=1"
    assert target.host_header == "hooks.example.org:8443"
    assert check_url("https://[2606:4700::1]/", targets="public").pinned_url == (
        "https://[2606:4700::1]:443/"
    )


@pytest.mark.parametrize(
    ("url", "refusal"),
    [
        ("https://8.8.8.8/hook", f"8.8.8.8 is a public address: {ONLY_LOOPBACK}"),
        ("https://10.0.0.1/hook", f"10.0.0.1 is a private address: {ONLY_LOOPBACK}"),
        ("https://192.168.1.1", f"192.168.1.1 is a private address: {ONLY_LOOPBACK}"),
        (
            "https://169.254.169.254/",
            f"169.254.169.254 is a link-local address: {ONLY_LOOPBACK}",
        ),
        (
            "https://example.com/hook",
            "example.com is not a loopback address: ACV_WEBHOOK_TARGETS=loopback allows "
            "127.0.0.1, ::1 and localhost only",
        ),
        ("http://example.com/hook", NOT_HTTPS),
        ("http://10.0.0.1/hook", NOT_HTTPS),
    ],
)
def test_the_loopback_setting_allows_loopback_only(url: str, refusal: str) -> None:
    """What the tests run with: a public address is refused too, and no name is looked up."""
    with pytest.raises(InputError) as refused:
        check_url(url, targets="loopback", resolve=no_lookup)
    assert str(refused.value) == refusal


@pytest.mark.parametrize(
    "url", ["http://127.0.0.1:9/hook", "http://localhost:9/", "https://[::1]/"]
)
def test_the_loopback_setting_allows_http_to_this_machine(url: str) -> None:
    assert check_url(url, targets="loopback", resolve=no_lookup).address.is_loopback


def test_every_kind_of_address_is_named() -> None:
    kinds = {
        a: address_kind(ipaddress.ip_address(a))
        for a in ("8.8.8.8", "10.0.0.1", "127.0.0.1", "169.254.1.1", "::", "ff02::1", "240.0.0.1")
    }
    assert kinds == {
        "8.8.8.8": "public",
        "10.0.0.1": "private",
        "127.0.0.1": "loopback",
        "169.254.1.1": "link-local",
        "::": "unspecified",
        "ff02::1": "multicast",
        "240.0.0.1": "reserved",
    }


def test_our_signature_is_standard_webhooks() -> None:
    """The ``standardwebhooks`` package verifies what we sign, and refuses a changed body
    or another secret."""
    secret = signing.new_secret()
    assert secret.startswith("whsec_")
    body = json.dumps({"type": "participant.finished", "data": {"study_id": 1}}).encode()
    headers = signing.headers(secret, msg_id="evt_1", timestamp=int(time.time()), body=body)
    assert headers["webhook-signature"].startswith("v1,")
    assert Verifier(secret).verify(body, headers) == json.loads(body)
    with pytest.raises(Exception, match="No matching signature"):
        Verifier(secret).verify(body.replace(b"1", b"2"), headers)
    with pytest.raises(Exception, match="No matching signature"):
        Verifier(signing.new_secret()).verify(body, headers)


def test_the_backoff_doubles_up_to_its_cap_with_jitter() -> None:
    policy, rng = Policy(backoff_s=5, backoff_cap_s=60), random.Random(0)
    for attempts, full in [(1, 5), (2, 10), (3, 20), (4, 40), (5, 60), (30, 60), (500, 60)]:
        waits = [policy.backoff(attempts, rng) for _ in range(50)]
        assert all(timedelta(seconds=full / 2) <= w <= timedelta(seconds=full) for w in waits)
        assert len(set(waits)) > 1  # jitter: a backlog does not come back at once
