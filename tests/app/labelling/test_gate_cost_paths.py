"""The gold gate at constant cost (issue 45 §7), on SQLite and PostgreSQL: a gold answer runs
on the labelling hot path, in no more statements than a label, the same number whatever the
study's size; the participant's gold standing it reads is the one the gate reads in full.
(Timings are ``benchmarks/gate_cost.py``'s; tests count statements only.)"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import event

from app.labelling import gold_answers, quality
from app.labelling.gold_answers import GoldScore
from app.recruiting.members import ParticipantRef
from app.studies import gold
from tests.support.crowd import configure
from tests.support.studies import Player
from tests.support.web import ADMIN

N = 8  # candidates: 7 bracket matches, gold positions 1..6
#: A gold answer's statements: the participant's lock, one read (item, progress, standing,
#: gate), the answer, the participant's activity, and the next match with any gold item due.
GOLD_STATEMENTS = 6


@pytest.fixture(scope="module")
def gated(client: TestClient, make_study: Callable[..., dict[str, Any]]) -> dict[str, Any]:
    """A study with two gold items and an excluding gate."""
    study = make_study(n_candidates=N, seed=5)
    for kind, a, b, answer in (("pair", 0, 1, 1), ("instructed", 2, 3, 2)):
        body = {"kind": kind, "a": a, "b": b, "answer": answer}
        made = client.post(f"/api/studies/{study['id']}/gold", json=body, headers=ADMIN)
        assert made.status_code == 201, made.text
    configure(client, study["id"], gold_gate=0.9, gate_excludes=True)
    return study


@contextmanager
def statements(client: TestClient) -> Iterator[list[str]]:
    """The statements the requests made meanwhile run (the app's own background threads,
    named ``acv-*``, left out: they poll whatever the requests do)."""
    seen: list[str] = []
    engine = client.app.state.runtime.engine  # type: ignore[attr-defined]

    def record(_conn: Any, _cursor: Any, statement: str, *_: Any) -> None:
        if not threading.current_thread().name.startswith("acv-"):
            seen.append(statement)

    event.listen(engine, "before_cursor_execute", record)
    try:
        yield seen
    finally:
        event.remove(engine, "before_cursor_execute", record)


def _counted_walk(client: TestClient, player: Player) -> tuple[list[int], list[int]]:
    """Play the bracket (``a`` wins, gold answered right); returns the statements of each
    gold answer and of each label."""
    gold_counts, label_counts = [], []
    while (match := player.next_match()) is not None:
        winner = match["a"]["candidate_id"]
        with statements(client) as seen:
            if match["gold"] is not None:
                sent = player.answer_gold(match["gold"]["item_id"], winner)
            else:
                sent = player.label(match["match_id"], winner)
        assert sent.status_code == 201, sent.text
        (gold_counts if match["gold"] is not None else label_counts).append(len(seen))
    return gold_counts, label_counts


def test_a_gold_answer_costs_no_more_statements_than_a_label_whatever_the_size(
    client: TestClient, gated: dict[str, Any], invite
) -> None:
    sid = gated["id"]
    small_gold, small_labels = _counted_walk(client, invite(sid))
    for _ in range(4):  # the study grows
        invite(sid).play()
    large_gold, large_labels = _counted_walk(client, invite(sid))
    assert len(small_gold) == len(large_gold) == 2
    assert small_gold == large_gold  # constant in the study's size
    assert max(large_gold) <= GOLD_STATEMENTS
    assert max(large_gold) <= min(large_labels)  # at most a label's cost


def test_sending_a_gold_answer_again_reads_only_and_the_other_way_conflicts(
    client: TestClient, gated: dict[str, Any], invite
) -> None:
    player = invite(gated["id"])
    while (match := player.next_match())["gold"] is None:
        assert player.label(match["match_id"], match["a"]["candidate_id"]).status_code == 201
    item, a, b = match["gold"]["item_id"], match["a"]["candidate_id"], match["b"]["candidate_id"]
    first = player.answer_gold(item, a)
    assert first.status_code == 201, first.text
    with statements(client) as seen:
        again = player.answer_gold(item, a)
    assert again.status_code == 200, again.text
    assert again.json() == {**first.json(), "created": False}
    assert not [s for s in seen if s.lstrip().upper().startswith(("INSERT", "DELETE"))]
    assert player.answer_gold(item, b).status_code == 409
    assert player.answer_gold(10**6, a).status_code == 404
    assert player.answer_gold(item, 10**6).status_code == 422


def test_the_standing_a_gold_answer_reads_is_the_gates_full_reading(
    client: TestClient, gated: dict[str, Any], invite, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each answer's incremental standing (read once, plus the answer) is the participant's
    gold score read in full, right or wrong, and the gate runs on it."""
    passed: list[tuple[int, GoldScore, float | None]] = []
    apply = quality.gate_after_answer

    def spy(sessions: Any, person: ParticipantRef, standing: GoldScore, gate: float | None):
        passed.append((person.id, standing, gate))
        return apply(sessions, person, standing, gate)

    monkeypatch.setattr(quality, "gate_after_answer", spy)
    sid, runtime = gated["id"], client.app.state.runtime  # type: ignore[attr-defined]
    with runtime.sessions() as session:
        items = {g.id: g.answer for g in gold.list_items(session, study_id=sid)}
    for right in (True, False):
        player, answers = invite(sid), 0
        while (match := player.next_match()) is not None:
            if match["gold"] is None:
                sent = player.label(match["match_id"], match["a"]["candidate_id"])
                if sent.status_code == 410:  # the gate stopped them
                    break
                assert sent.status_code == 201, sent.text
                continue
            item, sides = (
                match["gold"]["item_id"],
                {match["a"]["candidate_id"], match["b"]["candidate_id"]},
            )
            answer = items[item] if right else (sides - {items[item]}).pop()
            assert player.answer_gold(item, answer).status_code == 201
            answers += 1
            with runtime.sessions() as session:
                full = gold_answers.scores(session, study_id=sid, participant_id=player.id)
            assert passed[-1] == (player.id, full[player.id], 0.9)
            assert full[player.id] == GoldScore(answers if right else 0, answers)
        assert answers == 2
    # the careless one was stopped by the gate after their second failed item
    careless = client.get(f"/api/participants/{player.id}", headers=ADMIN).json()
    assert careless["outcome"] == "failed_gate"


def test_a_member_who_withdrew_answers_no_gold_item(
    client: TestClient, gated: dict[str, Any], invite
) -> None:
    """A gold answer takes the label's lock, so a participant who withdrew is refused (410)
    and nothing of theirs is stored, as for a label."""
    player = invite(gated["id"])
    while (match := player.next_match())["gold"] is None:
        assert player.label(match["match_id"], match["a"]["candidate_id"]).status_code == 201
    left = client.post(
        "/api/participants/me/withdraw", json={"withdraw": True}, headers=player.headers
    )
    assert left.status_code == 200, left.text
    with statements(client) as seen:
        refused = player.answer_gold(match["gold"]["item_id"], match["a"]["candidate_id"])
    assert refused.status_code == 410, refused.text
    assert not [s for s in seen if s.lstrip().upper().startswith("INSERT")]
