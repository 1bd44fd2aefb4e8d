"""Races: a match gets at most one label, whatever arrives at the same time."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError

from app.db import POOL_CAPACITY, make_engine, make_sessions
from app.main import create_app
from app.models import Label, Match


def test_same_label_sent_at_once_is_stored_once(invite, settings) -> None:
    player = invite()
    match = player.next_match()
    winner = match["a"]["candidate_id"]
    with ThreadPoolExecutor(8) as pool:
        codes = sorted(
            pool.map(lambda _: player.label(match["match_id"], winner).status_code, range(16))
        )
    assert codes == [200] * 15 + [201]
    assert _labels_of(settings, match["match_id"]) == 1


def test_conflicting_labels_at_once_keep_the_first(invite, settings) -> None:
    player = invite()
    match = player.next_match()
    sides = [match["a"]["candidate_id"], match["b"]["candidate_id"]] * 8
    with ThreadPoolExecutor(8) as pool:
        responses = list(pool.map(lambda w: player.label(match["match_id"], w), sides))
    stored = [r.json()["winner"] for r in responses if r.status_code == 201]
    assert len(stored) == 1
    for side, r in zip(sides, responses, strict=True):
        assert r.status_code == (
            201 if r.json().get("created") else 200 if side == stored[0] else 409
        )
    assert _labels_of(settings, match["match_id"]) == 1


def test_many_participants_at_once_each_label_stored_once(invite, settings) -> None:
    players = [invite() for _ in range(6)]
    with ThreadPoolExecutor(6) as pool:
        sent = list(pool.map(lambda p: p.play(), players))
    assert sent == [4] * 6
    engine = make_engine(settings.sqlalchemy_url)
    with make_sessions(engine)() as session:
        per_match = session.execute(
            select(Label.match_id, func.count())
            .join(Match, Match.id == Label.match_id)
            .where(Match.participant_id.in_([p.id for p in players]))
            .group_by(Label.match_id)
        ).all()
    engine.dispose()
    assert len(per_match) == 24 and {n for _, n in per_match} == {1}


def test_database_refuses_a_second_label_for_a_match(invite, settings) -> None:
    """The unique constraint itself, bypassing the service layer."""
    player = invite()
    match = player.next_match()
    player.label(match["match_id"], match["a"]["candidate_id"])
    engine = make_engine(settings.sqlalchemy_url)
    try:
        with make_sessions(engine)() as session, pytest.raises(IntegrityError):
            session.add(
                Label(
                    match_id=match["match_id"],
                    participant_id=player.id,
                    winner=match["b"]["candidate_id"],
                )
            )
            session.commit()
    finally:
        engine.dispose()


def _labels_of(settings, match_id: int) -> int:
    engine = make_engine(settings.sqlalchemy_url)
    try:
        with make_sessions(engine)() as session:
            return session.scalar(select(func.count()).where(Label.match_id == match_id))
    finally:
        engine.dispose()


def test_burst_larger_than_the_pool_with_one_worker_thread(settings, study, invite) -> None:
    """More requests at once than pooled connections, one worker thread: every request is
    answered (a request waiting for a thread must not hold a connection others wait for)."""
    players = [invite() for _ in range(4)]
    with TestClient(create_app(settings.model_copy(update={"threads": 1}))) as one_thread:

        def ask(k: int) -> int:
            return one_thread.get(
                "/api/participants/me",  # a sync handler
                headers=players[k % 4].headers,
            ).status_code

        with ThreadPoolExecutor(64) as pool:
            codes = list(pool.map(ask, range(POOL_CAPACITY + 24)))
    assert codes == [200] * (POOL_CAPACITY + 24)
