"""Standard Webhooks signatures (https://www.standardwebhooks.com): a ``whsec_`` secret and
the ``webhook-id``, ``webhook-timestamp`` and ``webhook-signature`` headers.

Written here with :mod:`hmac` rather than with the ``standardwebhooks`` package: the scheme
is these few lines, and the server then needs no dependency for them; the tests verify our
signatures with that package, so the two interoperate.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import secrets

SECRET_PREFIX = "whsec_"
#: Bytes of a new secret's key (the specification asks for 24 to 64).
KEY_BYTES = 32


def new_secret() -> str:
    """A fresh secret: ``whsec_`` and the base64 of random key bytes."""
    return SECRET_PREFIX + base64.b64encode(secrets.token_bytes(KEY_BYTES)).decode()


def signature(secret: str, *, msg_id: str, timestamp: int, body: bytes) -> str:
    """``v1,`` and the base64 HMAC-SHA256 of ``{id}.{timestamp}.{body}`` under the key."""
    key = base64.b64decode(secret.removeprefix(SECRET_PREFIX))
    signed = f"{msg_id}.{timestamp}.".encode() + body
    return "v1," + base64.b64encode(hmac.new(key, signed, hashlib.sha256).digest()).decode()


def headers(secret: str, *, msg_id: str, timestamp: int, body: bytes) -> dict[str, str]:
    """The three Standard Webhooks headers of one delivery attempt."""
    return {
        "webhook-id": msg_id,
        "webhook-timestamp": str(timestamp),
        "webhook-signature": signature(secret, msg_id=msg_id, timestamp=timestamp, body=body),
    }
