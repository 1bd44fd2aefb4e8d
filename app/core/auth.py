"""Credentials: the researcher's admin token, participants' invite tokens, and cookies.

Researchers send ``Authorization: Bearer <admin token>`` to the API; pages use an HttpOnly
SameSite cookie holding a login time and a random nonce signed with a key derived from the
admin token (never the token itself), accepted for ``ACV_SESSION_HOURS``. Participants send
``Authorization: Bearer <invite token>``, or carry the cookie that ``/p/<token>`` sets; their
tokens are checked by :func:`app.recruiting.members.resolve`, as respondents' are.
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import os
import secrets
import time
from pathlib import Path

from pydantic import SecretStr

from app.settings import Settings
from engine.errors import InputError

ADMIN_TOKEN_FILE = "admin_token"
DATASET_SALT_FILE = "dataset_salt"
RESEARCHER_COOKIE = "acv_researcher"
PARTICIPANT_COOKIE = "acv_participant"
RESPONDENT_COOKIE = "acv_respondent"
EVALUATOR_COOKIE = "acv_evaluator"
#: How long a member's browser remembers their invitation, so they can resume.
#: Shortest admin token accepted: ~190 bits as URL-safe base64, beyond brute force.
MIN_ADMIN_TOKEN_CHARS = 32
#: Seconds a researcher cookie may claim to come from the future (clocks of several hosts).
CLOCK_SKEW_S = 60
_MAX_TOKEN_CHARS = 256


def new_token() -> str:
    """A fresh unguessable token (256 bits, URL-safe)."""
    return secrets.token_urlsafe(32)


def ensure_admin_token(settings: Settings) -> str:
    """``ACV_ADMIN_TOKEN``, else the token kept in the data dir, made on first call.

    The file appears complete or not at all (written aside with mode 0600, then hard-linked
    into place, which fails if it exists), so processes starting together (several web
    workers) agree on one token and none reads a half-written file.

    Raises:
        InputError: the token is empty or shorter than :data:`MIN_ADMIN_TOKEN_CHARS` (it
            could be guessed, and the cookies and CSRF tokens are keyed by it).
    """
    return _kept_secret(
        settings.admin_token, "ACV_ADMIN_TOKEN", settings.data_dir / ADMIN_TOKEN_FILE, "admin token"
    )


def dataset_salt(settings: Settings) -> bytes:
    """The secret that keys participants' pseudonyms in a shared dataset
    (:mod:`app.labelling.dataset`): ``ACV_DATASET_SALT``, else a random one kept in the data
    dir, made on first call as the admin token is. It is not the admin token, so that
    changing the token keeps every pseudonym.

    Raises:
        InputError: the salt is empty or shorter than :data:`MIN_ADMIN_TOKEN_CHARS`.
    """
    where = settings.data_dir / DATASET_SALT_FILE
    return _kept_secret(settings.dataset_salt, "ACV_DATASET_SALT", where, "dataset salt").encode()


def _kept_secret(setting: SecretStr | None, variable: str, path: Path, what: str) -> str:
    """``setting`` (from ``variable``), else the secret kept at ``path``, made on first call."""
    if setting is not None:
        secret, where = setting.get_secret_value().strip(), variable
    else:
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists():
            _publish(path, new_token())
        secret, where = path.read_text(encoding="utf-8").strip(), str(path)
    if not secret:
        raise InputError(f"the {what} in {where} is empty")
    if len(secret) < MIN_ADMIN_TOKEN_CHARS:
        raise InputError(
            f"the {what} in {where} has {len(secret)} characters; use at least "
            f"{MIN_ADMIN_TOKEN_CHARS}, e.g. python3 -c 'import secrets; "
            f"print(secrets.token_urlsafe(32))'"
        )
    return secret


def _publish(path: Path, token: str) -> None:
    """Create ``path`` holding ``token`` atomically, unless another process did first."""
    aside = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}")
    fd = os.open(aside, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(token + "\n")
            f.flush()
            os.fsync(f.fileno())
        with contextlib.suppress(FileExistsError):  # someone else's token won: use theirs
            os.link(aside, path)
    finally:
        aside.unlink(missing_ok=True)


def same_secret(given: str | None, expected: str) -> bool:
    """Constant-time comparison that also accepts non-ASCII input (as bytes)."""
    if not given or len(given) > _MAX_TOKEN_CHARS:
        return False
    return secrets.compare_digest(given.encode(), expected.encode())


def bearer_token(authorization: str | None) -> str | None:
    """The token of an ``Authorization: Bearer <token>`` header, or ``None``."""
    if not authorization:
        return None
    scheme, _, token = authorization.partition(" ")
    if scheme.lower() != "bearer":
        return None
    return token.strip() or None


def _session_key(admin_token: str) -> bytes:
    return hmac.new(admin_token.encode(), b"acv-researcher-session", hashlib.sha256).digest()


def _sign(admin_token: str, payload: str) -> str:
    return hmac.new(_session_key(admin_token), payload.encode(), hashlib.sha256).hexdigest()


def researcher_cookie_value(*, admin_token: str, issued_at: float | None = None) -> str:
    """A new researcher cookie: ``<login time>.<nonce>.<signature>``, never the token; the
    nonce makes every login's cookie different."""
    issued = int(time.time() if issued_at is None else issued_at)
    payload = f"{issued}.{secrets.token_urlsafe(12)}"
    return f"{payload}.{_sign(admin_token, payload)}"


def valid_researcher_cookie(
    *, cookie: str | None, admin_token: str, max_age_s: float, now: float | None = None
) -> bool:
    """Whether ``cookie`` was signed with this admin token less than ``max_age_s`` ago."""
    if not cookie or len(cookie) > _MAX_TOKEN_CHARS or cookie.count(".") != 2:
        return False
    issued, nonce, signature = cookie.split(".")
    if not (issued.isascii() and issued.isdigit() and len(issued) <= 12) or not same_secret(
        signature, _sign(admin_token, f"{issued}.{nonce}")
    ):
        return False
    age = (time.time() if now is None else now) - int(issued)
    return -CLOCK_SKEW_S <= age <= max_age_s


def is_researcher(
    *,
    admin_token: str,
    bearer: str | None = None,
    cookie: str | None = None,
    max_age_s: float | None = None,
) -> bool:
    """Whether a bearer token, or a researcher cookie younger than ``max_age_s`` (the
    session length; without it no cookie counts), proves the researcher."""
    return same_secret(bearer, admin_token) or (
        max_age_s is not None
        and valid_researcher_cookie(cookie=cookie, admin_token=admin_token, max_age_s=max_age_s)
    )
