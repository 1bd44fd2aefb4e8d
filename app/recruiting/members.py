"""Members of a collection, and the one lookup of their invite tokens.

A *collection* is a study (bracket labelling; its members are participants, invited by
``/p/<token>``), a survey (tree reading; respondents, ``/r/<token>``) or an agent evaluation
(evaluators, ``/v/<token>``). Both kinds of
member are known only by an invite token, and :func:`resolve` is the one function that says
whom a raw token names, for either kind. It makes every check that the two earlier lookups
(``auth.participant_by_token`` and ``survey_respond.respondent_by_token``) made between them:

1. a token is sent, else "... invite token is required";
2. it has the shape of the tokens we issue (:func:`app.core.auth.new_token`): 1..256
   characters of URL-safe base64, hence ASCII. The study lookup checked this alphabet, the
   survey lookup only ASCII and the length; anything else is refused before any query;
3. the member is looked up by the token's SHA-256 digest (``token_hash``), never by the
   token itself, so an index's timing tells a guesser about the hash of a guess only;
4. the stored token is compared with the one sent in constant time;
5. where the caller names a collection, the member belongs to it (open links resume only
   their own collection's members; a survey's pages serve only its own respondents).

Neither lookup checked more, and this one adds nothing else on purpose: tokens neither
expire nor are revoked (no column says so), a finished member must still resolve (their
thank-you page, tree and completion code), a declined consent makes no member at all, and a
member exists only for a collection that can take one (a study's participants are made once
it is ready; a survey is open from its creation). A member whose row is gone (its
collection was deleted) is unknown.
"""

from __future__ import annotations

import functools
import re
import secrets
import weakref
from dataclasses import dataclass
from typing import Generic, TypeVar

from sqlalchemy import ColumnElement, Connection, Engine, Select, and_, bindparam, select
from sqlalchemy.orm import Session

from app.core import auth
from app.core.errors import AuthError
from app.db import engine_of
from app.models import (
    Evaluation,
    Evaluator,
    Member,
    OpenLink,
    Participant,
    Study,
    Survey,
    SurveyRespondent,
    token_digest,
)

#: What invite tokens look like (URL-safe base64); anything else is not looked up at all.
TOKEN_SHAPE = re.compile(r"[A-Za-z0-9_-]{1,256}")
#: Members remembered per process (see :func:`resolve`); past this the memory starts over.
MAX_KNOWN = 100_000

MemberRow = TypeVar("MemberRow", Participant, SurveyRespondent, Evaluator)


@dataclass(frozen=True)
class CollectionKind(Generic[MemberRow]):
    """A kind of collection (studies, surveys) as the people code needs to know it."""

    #: The collection's noun (``study``), its table's model, its members' model and noun
    #: (``participant``).
    noun: str
    collection: type[Study] | type[Survey] | type[Evaluation]
    member: type[MemberRow]
    person: str
    #: Where an invite link points (this prefix and the token), and the cookie it sets.
    invite_prefix: str
    cookie: str

    @property
    def people(self) -> str:
        """What the members are called together (``participants``)."""
        return f"{self.person}s"

    @property
    def missing(self) -> str:
        """What a caller who sent no token is told."""
        return f"a {self.person} invite token is required"

    @property
    def unknown(self) -> str:
        """What a caller whose token names nobody of this kind is told."""
        return f"unknown {self.person} invite token"

    def invite_path(self, token: str) -> str:
        """The path of a member's invite link."""
        return f"{self.invite_prefix}{token}"


STUDY = CollectionKind(
    noun="study",
    collection=Study,
    member=Participant,
    person="participant",
    invite_prefix="/p/",
    cookie=auth.PARTICIPANT_COOKIE,
)
SURVEY = CollectionKind(
    noun="survey",
    collection=Survey,
    member=SurveyRespondent,
    person="respondent",
    invite_prefix="/r/",
    cookie=auth.RESPONDENT_COOKIE,
)
EVALUATION = CollectionKind(
    noun="evaluation",
    collection=Evaluation,
    member=Evaluator,
    person="evaluator",
    invite_prefix="/v/",
    cookie=auth.EVALUATOR_COOKIE,
)


@dataclass(frozen=True)
class MemberRef:
    """A member as a token names them: no row object, no session (the hot path's key)."""

    id: int
    collection_id: int
    token: str


#: Members already resolved in this process, by database (engine), kind and token digest:
#: tokens never change and a member keeps their collection, so a known token needs no query
#: (a row deleted since is caught where it is read, see :func:`member_by_token`).
_known: weakref.WeakKeyDictionary[Engine, dict[tuple[str, str], MemberRef]] = (
    weakref.WeakKeyDictionary()
)


@functools.cache
def _by_digest(kind: CollectionKind[MemberRow]) -> Select[int, int, str]:
    return select(Member.id, Member.collection_id, Member.token).where(
        Member.token_hash == bindparam("digest"), Member.collection_kind == kind.noun
    )


def resolve(
    db: Session | Connection,
    kind: CollectionKind[MemberRow],
    *,
    token: str | None,
    collection_id: int | None = None,
) -> MemberRef:
    """The member of ``kind`` whose invite ``token`` this is, after every check listed in
    the module's docstring; ``collection_id``, when given, is the collection they must be in.

    Raises:
        AuthError: no token, or one that names no member of ``kind`` (of that collection).
    """
    ref = _lookup(db, kind, _digest(kind, token))
    if not _same(token, ref) or (collection_id is not None and ref.collection_id != collection_id):
        raise AuthError(kind.unknown)
    return ref


def _lookup(db: Session | Connection, kind: CollectionKind[MemberRow], digest: str) -> MemberRef:
    """The member whose token has ``digest``: from this process's memory, else by a query
    (then remembered)."""
    remembered = _known.setdefault(engine_of(db), {})
    if (ref := remembered.get((kind.noun, digest))) is not None:
        return ref
    row = db.execute(_by_digest(kind), {"digest": digest}).one_or_none()
    if row is None:
        raise AuthError(kind.unknown)
    if len(remembered) >= MAX_KNOWN:  # bounded memory; the busy ones come back at once
        remembered.clear()
    member_id, collection_id, token = row
    ref = remembered[(kind.noun, digest)] = MemberRef(member_id, collection_id, token)
    return ref


def _digest(kind: CollectionKind[MemberRow], token: str | None) -> str:
    """The digest ``token`` is looked up by, once it is sent and has the shape of ours."""
    if not token:
        raise AuthError(kind.missing)
    if not TOKEN_SHAPE.fullmatch(token):
        raise AuthError(kind.unknown)
    return token_digest(token)


def _same(token: str | None, ref: MemberRef) -> bool:
    """The token sent is the member's, compared in constant time."""
    return token is not None and secrets.compare_digest(token.encode(), ref.token.encode())


def known(engine: Engine, kind: CollectionKind[MemberRow], *, token: str | None) -> bool:
    """Whether :func:`resolve` accepts ``token`` from this process's memory alone (no query:
    the hot path checks a credential it has seen without a thread hop)."""
    if not token or not TOKEN_SHAPE.fullmatch(token):
        return False
    ref = _known.get(engine, {}).get((kind.noun, token_digest(token)))
    return ref is not None and _same(token, ref)


def member_by_token(
    session: Session,
    kind: CollectionKind[MemberRow],
    *,
    token: str | None,
    collection_id: int | None = None,
) -> MemberRow:
    """The row of the member :func:`resolve` finds.

    Raises:
        AuthError: as :func:`resolve`; or the member's row is gone.
    """
    ref = resolve(session, kind, token=token, collection_id=collection_id)
    member = session.get(kind.member, ref.id)
    if member is None:  # deleted with their collection since this process remembered them
        _known.get(engine_of(session), {}).pop((kind.noun, token_digest(ref.token)), None)
        raise AuthError(kind.unknown)
    return member


def of_collection(noun: str, collection_id: int) -> ColumnElement[bool]:
    """The condition on the members of collection ``collection_id`` of kind ``noun``
    (``study``): with :func:`link_of` and the token lookup's, the one place the kind filter
    is written."""
    return and_(Member.collection_kind == noun, Member.collection_id == collection_id)


def link_of(noun: str, collection_id: int) -> ColumnElement[bool]:
    """The condition on the open link row of collection ``collection_id`` of kind ``noun``."""
    return and_(OpenLink.collection_kind == noun, OpenLink.collection_id == collection_id)


def member_by_external_id(
    session: Session, kind: CollectionKind[MemberRow], *, collection_id: int, external_id: str
) -> MemberRow | None:
    """The member of ``kind`` in collection ``collection_id`` whose first external id is
    ``external_id`` (unique there), or ``None``."""
    return session.scalar(
        select(kind.member).where(
            of_collection(kind.noun, collection_id), Member.external_id == external_id
        )
    )


def member_by_join_key(
    session: Session, kind: CollectionKind[MemberRow], *, collection_id: int, join_key: str
) -> MemberRow | None:
    """The member of ``kind`` in collection ``collection_id`` who joined with the consent
    form's ``join_key`` (unique there), or ``None``."""
    return session.scalar(
        select(kind.member).where(
            of_collection(kind.noun, collection_id), Member.join_key == join_key
        )
    )


def is_member_token(db: Session | Connection, *, token: str) -> bool:
    """Whether ``token`` is some member's invite token, of any kind (a credential of another
    role, not a guess)."""
    return (
        _accepts(db, STUDY, token) or _accepts(db, SURVEY, token) or _accepts(db, EVALUATION, token)
    )


def _accepts(db: Session | Connection, kind: CollectionKind[MemberRow], token: str) -> bool:
    try:
        resolve(db, kind, token=token)
    except AuthError:
        return False
    return True


@dataclass(frozen=True)
class ParticipantRef:
    """A participant as the labelling hot path knows them (no row object, no session)."""

    id: int
    study_id: int
    token: str


def participant_ref(db: Session | Connection, *, token: str | None) -> ParticipantRef:
    """The participant holding invite ``token`` (:func:`resolve`, which
    remembers known tokens in this process, so the hot path needs no query for them).

    Raises:
        AuthError: missing or unknown token.
    """
    ref = resolve(db, STUDY, token=token)
    return ParticipantRef(ref.id, ref.collection_id, ref.token)
