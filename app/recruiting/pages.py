"""What the open-link pages of studies (``/s/<slug>``, :mod:`app.labelling.crowd_pages`) and
surveys (``/q/<slug>``, :mod:`app.surveys.crowd_pages`) share: the rate limit on new
people, the consent and message pages, and the researcher's open-link form.

Joining is rate-limited per client address (:mod:`app.http.ratelimit`, the same moving
window as failed logins, with its own counts, one for both kinds of link); only visits that
create a person count.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar
from urllib.parse import parse_qsl

from fastapi import Request, Response
from pydantic import BaseModel, ValidationError

from app.core.errors import TooManyAttemptsError
from app.http.ratelimit import client_address
from app.http.rendering import render
from app.models import CrowdSettings, SurveyCrowdSettings
from app.recruiting.links import DEFAULT_EXTERNAL_PARAMS
from app.recruiting.service import LinkKind
from engine.errors import InputError

T = TypeVar("T")
M = TypeVar("M", bound=BaseModel)
DECLINED = "You declined to take part; nothing about you was stored. You can close this page."


def admit(request: Request, join: Callable[[], T]) -> T:
    """``join()`` (make a new person through an open link), unless this client address made
    too many in the last minute.

    Raises:
        TooManyAttemptsError: 429 with Retry-After.
    """
    limiter, address = request.app.state.join_limiter, client_address(request)
    if limiter.blocked(address):
        raise TooManyAttemptsError(
            "Too many new participants from this address; try again in a minute.",
            retry_after_s=limiter.retry_after_s(address),
        )
    person = join()
    limiter.failed(address)  # counts a join
    return person


def query(request: Request) -> dict[str, str]:
    """The query's parameters (the last of a repeated name), bytes that are not UTF-8 kept as
    lone surrogates, so :func:`app.recruiting.links.external_ids` refuses them: decoded
    with replacement characters, as Starlette does, distinct raw ids would collide."""
    raw = request.scope["query_string"].decode("utf-8", "surrogateescape")
    return dict(parse_qsl(raw, keep_blank_values=True, errors="surrogateescape"))


def message(request: Request, name: str, title: str, text: str, status_code: int = 200) -> Response:
    """A plain page under the study's or survey's ``name``: full, declined, ..."""
    return render(
        request,
        "crowd_message.html",
        {"header_name": name, "title": title, "text": text},
        status_code=status_code,
    )


def full(request: Request, name: str, kind: LinkKind[Any, Any]) -> Response:
    """The page a visitor sees past the link's largest number of people."""
    title, text = kind.full
    return message(request, name, title, text)


def consent(
    request: Request,
    name: str,
    link: CrowdSettings | SurveyCrowdSettings,
    action: str,
    ids: dict[str, str],
) -> Response:
    """The consent page: the researcher's text, agree or decline (posted to ``action``)."""
    return render(
        request,
        "crowd_consent.html",
        {"header_name": name, "link": link, "action": action, "ids": ids},
    )


def link_form(fields: dict[str, str]) -> dict[str, Any]:
    """The open-link fields of a researcher's form, as the API's body would hold them."""
    text = {
        k: fields.get(k, "").strip() or None
        for k in ("consent_text", "completion_code", "redirect_url")
    }
    params = [p.strip() for p in fields.get("external_params", "").split(",") if p.strip()]
    return {
        "enabled": fields.get("enabled") == "on",
        "max_participants": whole(fields, "max_participants"),
        "external_params": params or list(DEFAULT_EXTERNAL_PARAMS),
        **text,
    }


def validated(schema: type[M], data: dict[str, Any]) -> M:
    """``data`` validated like the API's body; the first error as an :class:`InputError`."""
    try:
        return schema.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        raise InputError(f"{'.'.join(map(str, first['loc']))}: {first['msg']}") from None


def whole(fields: dict[str, str], name: str) -> int:
    try:
        return int(fields.get(name, "").strip())
    except ValueError:
        raise InputError(f"{name} must be a whole number") from None
