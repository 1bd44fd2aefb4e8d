"""``PUT``/``GET /api/<collections>/{id}/crowd``: a collection's open link and its options
(issue 14), one router built for each kind of collection (issue 26). Researcher only.

No ``from __future__ import annotations`` here: the routes' annotations name the kind's own
body model, a closure variable that FastAPI must read as a class, not as a string.
"""

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any, Generic

from fastapi import APIRouter, Path, Request
from pydantic import BaseModel
from sqlalchemy.orm import Session

from app.core.json_types import IntParam
from app.core.limits import MAX_DB_ID
from app.core.rows import from_row
from app.http.deps import ResearcherDep, SessionDep
from app.recruiting import service as recruiting
from app.recruiting.kinds import Link, MemberKind, open_url
from app.recruiting.links import LinkOptions
from app.recruiting.members import MemberRow
from app.recruiting.schemas import OpenLinkIn


@dataclass(frozen=True)
class LinkApi(Generic[Link, MemberRow]):
    """What one kind of collection's open-link API reads and writes."""

    kind: MemberKind[Link, MemberRow]
    #: The collections' path segment under ``/api`` (``studies``), their OpenAPI tag, and
    #: the routes' names (``set_<name>``, ``get_<name>``: the OpenAPI operation ids).
    collections: str
    tag: str
    name: str
    #: The request body (:class:`OpenLinkIn`, or a subclass with the kind's own options) and
    #: the response: the body's fields with ``<noun>_id``, ``slug``, ``url`` and the counts.
    body: type[OpenLinkIn]
    out: type[BaseModel]
    #: The options the body becomes, and what stores them for a collection id: by default
    #: :func:`recruiting.configure`; a kind with its own options checks them first.
    options: type[LinkOptions] = LinkOptions
    configure: Callable[[Session, int, Any], Link] | None = None
    #: Response fields that are not columns of the link (a survey's ``completed``).
    counts: Callable[[Session, Link], dict[str, int]] = lambda session, link: {}


def open_link_api_router(api: LinkApi[Link, MemberRow]) -> APIRouter:
    """``PUT`` and ``GET /<collections>/{<noun>_id}/crowd`` for ``api``'s kind of collection."""
    noun, link = api.kind.members.noun, api.kind.prefix
    id_name = f"{noun}_id"
    CollectionId = Annotated[int, IntParam(ge=1, le=MAX_DB_ID), Path(alias=id_name)]
    router = APIRouter(prefix=f"/{api.collections}", tags=[api.tag])
    path = f"/{{{id_name}}}/crowd"

    def out(request: Request, session: Session, row: Link) -> BaseModel:
        url = open_url(api.kind, request.base_url, row.slug)
        return from_row(api.out, row, url=url, **api.counts(session, row))

    own = ", and its own options" if api.body is not OpenLinkIn else ""
    set_doc = (
        f"Set the {noun}'s open link ``{link}<slug>``: on or off, largest number of "
        f"{api.kind.members.people}, external id parameters, consent text, completion code and "
        f"redirect URL{own}."
    )
    get_doc = f"The {noun}'s open link, options and counts; 404 until they are set."

    @router.put(path, response_model=api.out, name=f"set_{api.name}", description=set_doc)
    def set_crowd(
        collection_id: CollectionId,
        # A value, not a type, to mypy; FastAPI reads it as the kind's body class.
        body: api.body,  # type: ignore[name-defined]
        request: Request,
        session: SessionDep,
        _: ResearcherDep,
    ) -> BaseModel:
        options = body.options(api.options)
        if api.configure is None:
            return out(
                request, session, recruiting.configure(session, api.kind, collection_id, options)
            )
        return out(request, session, api.configure(session, collection_id, options))

    @router.get(path, response_model=api.out, name=f"get_{api.name}", description=get_doc)
    def get_crowd(
        collection_id: CollectionId, request: Request, session: SessionDep, _: ResearcherDep
    ) -> BaseModel:
        return out(request, session, recruiting.configured(session, api.kind, collection_id))

    return router
