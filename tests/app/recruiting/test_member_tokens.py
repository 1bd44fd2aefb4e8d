"""One token lookup for both kinds of collection (issue 26): every check that
:func:`app.recruiting.members.resolve` makes, run against a study's participants and a survey's
respondents alike, through the API and the database (SQLite and PostgreSQL), and proof that
both kinds resolve their tokens through that one function."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import delete, update

from app.core import auth
from app.core.errors import AuthError
from app.http.ratelimit import LoginLimiter
from app.models import Member, token_digest
from app.recruiting import members
from app.recruiting.members import STUDY, SURVEY, CollectionKind
from app.surveys import respond as survey_respond
from tests.support.studies import Player
from tests.support.surveys import (
    Respondent,
    invite,
    paper_answers,
    paper_body,
    participant_trees,
)
from tests.support.web import ADMIN, browser

#: Tokens of a shape we never issue: each is refused as unknown before any query.
MALFORMED = ("not a token!", "a" * 257, "tok%en", "t.o.k", "tökén")


@dataclass(frozen=True)
class Collection:
    """A study or a survey, and how its members reach the API."""

    kind: CollectionKind[Any]
    id: int
    client: TestClient
    me: str  # the member's own resource: any valid token of the kind gets 200
    cookie: str
    add: Callable[[], tuple[int, str]]  # invite a member: (id, token)
    finish: Callable[[int, str], None]  # answer everything as the member (id, token)

    def ask(self, token: str | None = None, *, cookie: bool = False) -> Any:
        if token is None:
            return self.client.get(self.me)
        if cookie:
            return browser(self.client, cookies={self.cookie: token}).get(self.me)
        return self.client.get(self.me, headers={"Authorization": f"Bearer {token}"})


@pytest.fixture(scope="module")
def survey(client: TestClient, study: dict[str, Any]) -> dict[str, Any]:
    made = client.post(
        "/api/surveys", json=paper_body(*participant_trees(client, study["id"])), headers=ADMIN
    )
    assert made.status_code == 201, made.text
    return made.json()


def _study(client: TestClient, study: dict[str, Any]) -> Collection:
    def add() -> tuple[int, str]:
        body = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
        return body["id"], body["token"]

    def finish(member_id: int, token: str) -> None:
        Player(client, member_id, token, "").play()

    return Collection(
        STUDY, study["id"], client, "/api/participants/me", auth.PARTICIPANT_COOKIE, add, finish
    )


def _survey(client: TestClient, survey: dict[str, Any]) -> Collection:
    def add() -> tuple[int, str]:
        [person] = invite(client, survey["id"])
        return person.id, person.token

    def finish(member_id: int, token: str) -> None:
        person = Respondent(client, member_id, token, "")
        while (screen := person.screen()) is not None:
            assert person.answer(screen["position"], paper_answers(screen)).status_code == 201

    return Collection(
        SURVEY,
        survey["id"],
        client,
        "/api/surveys/me",
        survey_respond.RESPONDENT_COOKIE,
        add,
        finish,
    )


@pytest.fixture(params=["study", "survey"])
def collection(request, client, study, survey) -> Collection:
    if request.param == "study":
        return _study(client, study)
    return _survey(client, survey)


@pytest.fixture
def other(client, study, survey, collection: Collection) -> Collection:
    """The other kind of collection."""
    return _survey(client, survey) if collection.kind is STUDY else _study(client, study)


def _detail(response: Any) -> str:
    return response.json()["detail"]


def test_a_valid_token_resolves_by_bearer_and_by_cookie(collection: Collection) -> None:
    _, token = collection.add()
    assert collection.ask(token).status_code == 200
    assert collection.ask(token, cookie=True).status_code == 200


def test_a_missing_token_is_required(collection: Collection) -> None:
    response = collection.ask()
    assert response.status_code == 401
    assert _detail(response) == collection.kind.missing


@pytest.mark.parametrize("token", MALFORMED[:4])
def test_a_token_of_another_shape_is_unknown(collection: Collection, token: str) -> None:
    """Checked by shape (the alphabet and length of the tokens issued): the survey lookup
    once answered "required" for these, the study lookup "unknown"; both say unknown now."""
    response = collection.ask(token)
    assert response.status_code == 401
    assert _detail(response) == collection.kind.unknown


def test_malformed_tokens_are_refused_without_a_query(
    collection: Collection, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Non-ASCII included (no HTTP client sends it in a header, a cookie may carry it)."""
    with collection.client.app.state.runtime.sessions() as session:

        def no_query(*_: Any, **__: Any) -> None:
            raise AssertionError("a malformed token reached the database")

        monkeypatch.setattr(session, "execute", no_query)
        for token in MALFORMED:
            with pytest.raises(AuthError, match=collection.kind.unknown):
                members.resolve(session, collection.kind, token=token)


def test_an_unknown_token_is_unknown(collection: Collection) -> None:
    response = collection.ask(auth.new_token())
    assert response.status_code == 401
    assert _detail(response) == collection.kind.unknown


def test_a_token_of_the_other_kind_is_unknown(collection: Collection, other: Collection) -> None:
    _, token = other.add()
    response = collection.ask(token)
    assert response.status_code == 401
    assert _detail(response) == collection.kind.unknown


def test_a_lookup_by_digest_is_confirmed_in_constant_time(
    collection: Collection, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A row found by the digest of a forged token (as if the hashes collided) is not
    enough: the stored token itself must match, compared by :func:`secrets.compare_digest`."""
    member_id, token = collection.add()
    forged = auth.new_token()
    with collection.client.app.state.runtime.sessions() as session, session.begin():
        session.execute(
            update(Member).where(Member.id == member_id).values(token_hash=token_digest(forged))
        )
    compared: list[tuple[bytes, bytes]] = []
    real = members.secrets.compare_digest

    def spy(given: bytes, stored: bytes) -> bool:
        compared.append((given, stored))
        return real(given, stored)

    monkeypatch.setattr(members.secrets, "compare_digest", spy)
    response = collection.ask(forged)
    assert response.status_code == 401
    assert _detail(response) == collection.kind.unknown
    assert (forged.encode(), token.encode()) in compared


def test_a_finished_member_still_resolves(collection: Collection) -> None:
    """Thank-you pages, trees and completion codes need the finished member."""
    member_id, token = collection.add()
    collection.finish(member_id, token)
    response = collection.ask(token)
    assert response.status_code == 200
    assert response.json()["finished"] is True


def test_a_member_of_another_collection_is_unknown_where_a_collection_is_named(
    collection: Collection,
) -> None:
    member_id, token = collection.add()
    with collection.client.app.state.runtime.sessions() as session:
        ref = members.resolve(session, collection.kind, token=token, collection_id=collection.id)
        assert (ref.id, ref.collection_id) == (member_id, collection.id)
        with pytest.raises(AuthError, match=collection.kind.unknown):
            members.resolve(session, collection.kind, token=token, collection_id=collection.id + 1)


def test_a_member_whose_row_is_gone_is_unknown(collection: Collection) -> None:
    """Remembered tokens need no query, but a row read is checked: the invite link of a
    member deleted since (with their collection) is not valid."""
    member_id, token = collection.add()
    link = collection.kind.invite_path(token)
    page = browser(collection.client)
    assert page.get(link).status_code == 303  # remembered in this process from now on
    model = collection.kind.member
    with collection.client.app.state.runtime.sessions() as session, session.begin():
        session.execute(delete(model).where(model.id == member_id))
    assert page.get(link).status_code == 404


def test_a_member_token_sent_as_the_researcher_is_no_guess(collection: Collection) -> None:
    """A member's own token is a credential of another role: it does not count as a failed
    researcher login, so it never locks the researcher out."""
    _, token = collection.add()
    app = collection.client.app
    saved, app.state.login_limiter = app.state.login_limiter, LoginLimiter(1)
    try:
        for _ in range(3):
            answer = collection.client.get(
                "/api/studies", headers={"Authorization": f"Bearer {token}"}
            )
            assert answer.status_code == 401
        assert collection.client.get("/api/studies", headers=ADMIN).status_code == 200
    finally:
        app.state.login_limiter = saved


def test_both_kinds_resolve_tokens_through_one_function(
    collection: Collection, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The member's API, their cookie, their invite page and the researcher's guard all go
    through :func:`members.resolve` with this kind; the two old copies are gone."""
    seen: list[str] = []
    real = members.resolve

    def spy(db: Any, kind: CollectionKind[Any], **kwargs: Any) -> members.MemberRef:
        seen.append(kind.noun)
        return real(db, kind, **kwargs)

    monkeypatch.setattr(members, "resolve", spy)
    _, token = collection.add()
    client = collection.client
    for ask in (
        lambda: collection.ask(token),
        lambda: collection.ask(token, cookie=True),
        lambda: browser(client).get(collection.kind.invite_path(token)),
        lambda: client.get("/api/studies", headers={"Authorization": f"Bearer {token}"}),
    ):
        seen.clear()
        ask()
        assert collection.kind.noun in seen
    assert not hasattr(auth, "participant_by_token")
    assert not hasattr(survey_respond, "respondent_by_token")
