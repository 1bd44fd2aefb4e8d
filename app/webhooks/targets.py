"""Where a webhook may point (server-side request forgery): checked when a researcher
registers the URL, before any request is made, and again before every delivery on the
addresses its host resolves to then, so a name that later resolves to a private address
(DNS rebinding) is refused too. The delivery connects to the address checked here.

Rules, in the order they are checked (the first broken one is the refusal):

1. an ``https`` URL of at most 2000 printable characters, without credentials; ``http``
   only to a loopback host when ``ACV_WEBHOOK_TARGETS=loopback`` (tests);
2. every address the host resolves to is public: never private, loopback, link-local
   (cloud metadata at 169.254.169.254), multicast, reserved, shared or unspecified. With
   ``ACV_WEBHOOK_TARGETS=loopback`` it is the other way round: only 127.0.0.1 and ::1 (and
   ``localhost``, never looked up in DNS), so tests send traffic to this machine only.
"""

from __future__ import annotations

import ipaddress
import socket
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal
from urllib.parse import SplitResult, urlsplit

from engine.errors import InputError

Targets = Literal["public", "loopback"]
IPAddress = ipaddress.IPv4Address | ipaddress.IPv6Address
Resolver = Callable[[str, int], list[IPAddress]]
MAX_URL_CHARS = 2000
LOCALHOST = "localhost"
DEFAULT_PORTS = {"https": 443, "http": 80}
_MODE = {"public": "public", "loopback": "loopback (ACV_WEBHOOK_TARGETS=loopback)"}


@dataclass(frozen=True)
class Target:
    """A checked URL: where to connect (``address``, ``port``) and what to ask for there."""

    scheme: str
    host: str
    port: int
    path: str
    address: IPAddress

    @property
    def pinned_url(self) -> str:
        """The URL with the checked address in place of the host (no second lookup)."""
        shown = f"[{self.address}]" if self.address.version == 6 else str(self.address)
        return f"{self.scheme}://{shown}:{self.port}{self.path}"

    @property
    def host_header(self) -> str:
        """The ``Host`` header the receiver expects (the host as registered)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return host if self.port == DEFAULT_PORTS[self.scheme] else f"{host}:{self.port}"


def address_kind(address: IPAddress) -> str:
    """``public``, or the kind of non-public address (``private``, ``loopback``, ...)."""
    if isinstance(address, ipaddress.IPv6Address):
        # ::ffff:10.0.0.1 is 10.0.0.1, and 2002:0a00:0001:: (6to4) routes to it
        embedded = address.ipv4_mapped or address.sixtofour
        address = embedded if embedded is not None else address
    for kind in ("unspecified", "loopback", "link_local", "multicast", "reserved", "private"):
        if getattr(address, f"is_{kind}"):
            return kind.replace("_", "-")
    return "public" if address.is_global else "special-purpose"


def check_url(url: str, *, targets: Targets, resolve: Resolver | None = None) -> Target:
    """The URL's target when every rule holds (see the module), else the first refusal.

    Args:
        targets: ``public`` (production) or ``loopback`` (tests).
        resolve: looks a host name up (default :func:`getaddrinfo`); never called for an
            IP address, nor in loopback mode.

    Raises:
        InputError: the URL breaks a rule; the message names it.
    """
    parts = _split(url)
    host = parts.hostname or ""
    literal = _literal(host)
    loopback_host = host == LOCALHOST or (literal is not None and literal.is_loopback)
    if parts.scheme != "https" and not (targets == "loopback" and loopback_host):
        raise InputError(
            "a webhook URL must be https (http only to a loopback address in tests, "
            "ACV_WEBHOOK_TARGETS=loopback)"
        )
    port = _port(parts)
    addresses = [literal] if literal is not None else _lookup(host, port, targets, resolve)
    for address in addresses:
        _check_address(host, address, targets)
    return Target(parts.scheme, host, port, _path(parts), addresses[0])


def _split(url: str) -> SplitResult:
    if len(url) > MAX_URL_CHARS or not url.isprintable() or " " in url:
        raise InputError(f"a webhook URL is at most {MAX_URL_CHARS} printable characters")
    try:
        parts = urlsplit(url)
    except ValueError as exc:
        raise InputError(f"not a URL: {exc}") from None
    if parts.scheme not in ("https", "http") or not parts.hostname:
        raise InputError("a webhook URL must be https://host/path")
    if parts.username is not None or parts.password is not None:
        raise InputError("a webhook URL must not hold credentials (user:password@)")
    return parts


def _literal(host: str) -> IPAddress | None:
    try:
        return ipaddress.ip_address(host)
    except ValueError:
        return None


def _port(parts: SplitResult) -> int:
    try:
        port = parts.port
    except ValueError:
        raise InputError("the webhook URL's port must be in 1..65535") from None
    if port == 0:
        raise InputError("the webhook URL's port must be in 1..65535")
    return port or DEFAULT_PORTS[parts.scheme]


def _path(parts: SplitResult) -> str:
    return (parts.path or "/") + (f"?{parts.query}" if parts.query else "")


def _lookup(host: str, port: int, targets: Targets, resolve: Resolver | None) -> list[IPAddress]:
    """The host's addresses; in loopback mode only ``localhost``, never asked of DNS."""
    if targets == "loopback":
        if host != LOCALHOST:
            raise InputError(
                f"{host} is not a loopback address: ACV_WEBHOOK_TARGETS=loopback allows "
                "127.0.0.1, ::1 and localhost only"
            )
        return [ipaddress.ip_address("127.0.0.1")]
    found = (resolve or getaddrinfo)(host, port)
    if not found:
        raise InputError(f"{host} has no address")
    return found


def getaddrinfo(host: str, port: int) -> list[IPAddress]:
    """Every address ``host`` resolves to (TCP).

    Raises:
        InputError: the name does not resolve.
    """
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as exc:
        raise InputError(f"{host} does not resolve: {exc}") from None
    return [ipaddress.ip_address(str(info[4][0]).split("%")[0]) for info in infos]


def _check_address(host: str, address: IPAddress, targets: Targets) -> None:
    kind = address_kind(address)
    if kind == ("loopback" if targets == "loopback" else "public"):
        return
    named = host if _literal(host) is not None else f"{host} ({address})"
    article = "an" if kind[0] in "aeiou" else "a"
    raise InputError(
        f"{named} is {article} {kind} address: webhooks may only go to {_MODE[targets]} addresses"
    )
