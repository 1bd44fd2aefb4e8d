"""Gold pairs, the gold gate and practice in agent evaluations (issue 41: "gold items and the
gate apply"), through the API on both databases: the studies' instructed gold items, gate
and practice, applied to evaluators.

The stimuli are rolled out and rendered for real, as in ``test_evaluations_api.py``.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from PIL import Image
from sqlalchemy import func, select

from app.evaluations import gold
from app.evaluations.stimuli import stimuli_dir
from app.labelling.gold_answers import GoldScore
from app.models import Evaluation, EvaluationPair, EvaluationStimulus, Evaluator
from engine.render.image import with_marker
from tests.support.evaluations import evaluable_experiment, wait_evaluation
from tests.support.runs import run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN, csrf_token, logged_in

#: Real pairs per evaluator, and gold and practice pairs.
REAL, GOLD, PRACTICE = 4, 3, 2


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def experiment(client: TestClient) -> dict[str, Any]:
    study = new_study(client, n_candidates=5, seed=41)
    return evaluable_experiment(client, study["id"], seeds=2)


@pytest.fixture(scope="module")
def evaluation(client: TestClient, experiment: dict[str, Any]) -> dict[str, Any]:
    body = {
        "pairs_per_evaluator": REAL,
        "stimulus": "clip",
        "gold_pairs": GOLD,
        "gold_gate": 0.9,
        "practice_pairs": PRACTICE,
    }
    response = client.post(
        f"/api/experiments/{experiment['id']}/evaluations", json=body, headers=ADMIN
    )
    assert response.status_code == 201, response.text
    found = response.json()
    assert (found["gold_pairs"], found["gold_gate"], found["practice_pairs"]) == (3, 0.9, 2)
    return wait_evaluation(client, found["id"], clips=True)


def _invite(client: TestClient, evaluation: dict[str, Any]) -> dict[str, Any]:
    response = client.post(
        f"/api/evaluations/{evaluation['id']}/evaluators", json={"count": 1}, headers=ADMIN
    )
    assert response.status_code == 201, response.text
    return response.json()[0]


def _bearer(person: dict[str, Any]) -> dict[str, str]:
    return {"Authorization": f"Bearer {person['invite_url'].rsplit('/', 1)[1]}"}


def _rows(client: TestClient, evaluator_id: int) -> dict[str, EvaluationPair]:
    with client.app.state.runtime.sessions() as session:
        query = select(EvaluationPair).where(EvaluationPair.evaluator_id == evaluator_id)
        return {p.key: p for p in session.scalars(query)}


def _answer_all(
    client: TestClient, person: dict[str, Any], *, gold_right: bool
) -> list[dict[str, Any]]:
    """Answer every pair: the real ones ``left``, the gold ones right or wrong."""
    headers, rows, shown = _bearer(person), _rows(client, person["id"]), []
    while (got := client.get("/api/evaluators/me/pairs/next", headers=headers)).status_code == 200:
        pair = got.json()
        shown.append(pair)
        row = rows[pair["key"]]
        choice = "left"
        if row.gold_answer is not None:
            marked_left = (row.gold_answer == row.a) == row.a_left
            choice = "left" if marked_left == gold_right else "right"
        answer = client.post(
            f"/api/evaluators/me/pairs/{pair['key']}", json={"choice": choice}, headers=headers
        )
        assert answer.status_code == 200, answer.text
    assert got.status_code == 204
    return shown


def test_gold_pairs_are_placed_among_the_real_ones_and_marked(client, evaluation) -> None:
    """Each evaluator has the real pairs and the gold pairs, the gold ones after a first
    real pair and before the last; a gold pair looks like any other (an opaque key, the same
    fields) but shows stills only, the marker drawn on its answer's."""
    person = _invite(client, evaluation)
    assert person["total"] == REAL + GOLD
    rows = sorted(_rows(client, person["id"]).values(), key=lambda p: p.position)
    golds = [p for p in rows if p.gold_answer is not None]
    assert len(golds) == GOLD and all(p.gold_answer in (p.a, p.b) for p in golds)
    assert rows[0].gold_answer is None and rows[-1].gold_answer is None
    headers = _bearer(person)
    pair = _next_gold(client, headers, rows)
    assert set(pair) == {"key", "position", "total", "question", "left", "right", "reminder"}
    assert pair["question"] == gold.INSTRUCTED_PROMPT
    assert set(pair["left"]) == set(pair["right"]) == {"still"}
    row = next(p for p in golds if p.key == pair["key"])
    for side in ("left", "right"):
        slot, window = (
            (row.a, row.window_a) if (side == "left") == row.a_left else (row.b, row.window_b)
        )
        got = client.get(pair[side]["still"], headers=headers)
        assert got.status_code == 200 and Image.open(io.BytesIO(got.content)).format == "JPEG"
        plain = _still(client, evaluation["id"], slot, window)
        assert got.content == (with_marker(plain) if slot == row.gold_answer else plain)
    clip = pair["left"]["still"].replace("/still", "/clip")
    assert client.get(clip, headers=headers).status_code == 404


def _next_gold(
    client: TestClient, headers: dict[str, str], rows: list[EvaluationPair]
) -> dict[str, Any]:
    """Answer real pairs until a gold pair is next, and return it."""
    by_key = {p.key: p for p in rows}
    while True:
        pair = client.get("/api/evaluators/me/pairs/next", headers=headers).json()
        if by_key[pair["key"]].gold_answer is not None:
            return pair
        assert pair["question"] != gold.INSTRUCTED_PROMPT
        url = f"/api/evaluators/me/pairs/{pair['key']}"
        assert client.post(url, json={"choice": "left"}, headers=headers).status_code == 200


def _still(client: TestClient, evaluation_id: int, slot: int, window: int) -> bytes:
    with client.app.state.runtime.sessions() as session:
        found = session.get(EvaluationStimulus, (evaluation_id, slot, window))
        assert found is not None
        path = found.still_path
    return (stimuli_dir(client.app.state.runtime.settings.data_dir) / path).read_bytes()


def test_gold_answers_are_scored_and_the_gate_leaves_out_the_careless(client, evaluation) -> None:
    """Right gold answers keep an evaluator; wrong ones, once clearly below the gate, exclude
    them with the reason. The result and the export count only the real answers of kept
    evaluators: no gold pair, nobody the gate left out; the page says how many it left out."""
    before = _result(client, evaluation)["n_answers"]
    careful, careless = _invite(client, evaluation), _invite(client, evaluation)
    _answer_all(client, careful, gold_right=True)
    _answer_all(client, careless, gold_right=False)
    with client.app.state.runtime.sessions() as session:
        assert gold.score(session, evaluator_id=careful["id"]) == GoldScore(GOLD, GOLD)
        assert gold.score(session, evaluator_id=careless["id"]) == GoldScore(0, GOLD)
        kept, dropped = (session.get(Evaluator, p["id"]) for p in (careful, careless))
        assert kept is not None and dropped is not None
        assert not kept.excluded and kept.exclusion_reason is None
        assert dropped.excluded and (dropped.exclusion_reason or "").startswith("gold gate: 0 of")
        assert gold.gate_excluded(session, evaluation_id=evaluation["id"]) >= 1
    assert _result(client, evaluation)["n_answers"] == before + REAL
    response = client.get(f"/api/evaluations/{evaluation['id']}/answers.csv", headers=ADMIN)
    rows = list(csv.DictReader(io.StringIO(response.text)))
    assert {int(r["evaluator_id"]) for r in rows} >= {careful["id"]}
    assert careless["id"] not in {int(r["evaluator_id"]) for r in rows}
    assert sum(int(r["evaluator_id"]) == careful["id"] for r in rows) == REAL
    listed = client.get(f"/api/evaluations/{evaluation['id']}/evaluators", headers=ADMIN).json()
    assert next(p for p in listed if p["id"] == careless["id"])["excluded"]
    page = logged_in(client).get(f"/evaluations/{evaluation['id']}")
    assert page.status_code == 200 and 'id="gate-excluded"' in page.text


def test_practice_comes_first_and_never_after_an_answer(client, evaluation) -> None:
    """Practice pairs, the same on every reload, with right-or-wrong feedback on instructed
    pairs and none on the others, nothing stored; gone once the evaluator has answered."""
    person = _invite(client, evaluation)
    headers = _bearer(person)
    pairs = client.get("/api/evaluators/me/practice", headers=headers).json()
    assert len(pairs) == PRACTICE
    assert pairs == client.get("/api/evaluators/me/practice", headers=headers).json()
    assert {p["kind"] for p in pairs} <= {"instructed", "preference"}
    for pair in pairs:
        for url in (pair["left_url"], pair["right_url"]):
            got = client.get(url, headers=headers)
            assert got.status_code == 200 and Image.open(io.BytesIO(got.content)).format == "JPEG"
        said = client.post(
            pair["left_url"].split("/image")[0] + "/answer", json={"side": "left"}, headers=headers
        )
        assert said.status_code == 200, said.text
        body = said.json()
        assert (body["correct"] is None) == (pair["kind"] == "preference")
    assert _rows(client, person["id"]) and all(
        p.answered_at is None for p in _rows(client, person["id"]).values()
    )
    first = client.get("/api/evaluators/me/pairs/next", headers=headers).json()
    url = f"/api/evaluators/me/pairs/{first['key']}"
    assert client.post(url, json={"choice": "tie"}, headers=headers).status_code == 200
    assert client.get("/api/evaluators/me/practice", headers=headers).json() == []
    again = client.post(
        "/api/evaluators/me/practice/0/answer", json={"side": "left"}, headers=headers
    )
    assert again.status_code == 404


def test_practice_pictures_are_not_the_evaluations_agents(client, evaluation) -> None:
    """Practice shows practice states of the env, never a still of the evaluation."""
    person = _invite(client, evaluation)
    headers = _bearer(person)
    with client.app.state.runtime.sessions() as session:
        query = select(EvaluationStimulus.still_path).where(
            EvaluationStimulus.evaluation_id == evaluation["id"]
        )
        paths = list(session.scalars(query))
    folder = stimuli_dir(client.app.state.runtime.settings.data_dir)
    stills = {(folder / p).read_bytes() for p in paths}
    for pair in client.get("/api/evaluators/me/practice", headers=headers).json():
        for url in (pair["left_url"], pair["right_url"]):
            assert client.get(url, headers=headers).content not in stills


def test_the_evaluator_pages_start_with_practice(client, evaluation) -> None:
    person = _invite(client, evaluation)
    browser = TestClient(client.app)
    page = browser.get("/v/" + person["invite_url"].rsplit("/", 1)[1])
    assert page.status_code == 200 and 'href="/evaluate/practice"' in page.text
    assert "Start practice" in page.text
    practice = browser.get("/evaluate/practice")
    assert practice.status_code == 200 and "Practice pair 1 of 2" in practice.text
    feedback = browser.get("/evaluate/practice", params={"pair": 1, "chose": "left"})
    assert feedback.status_code == 200 and 'id="feedback"' in feedback.text
    assert 'href="/evaluate/pair"' in feedback.text and "Start the evaluation" in feedback.text


def _result(client: TestClient, evaluation: dict[str, Any]) -> dict[str, Any]:
    response = client.get(f"/api/evaluations/{evaluation['id']}/result", headers=ADMIN)
    assert response.status_code == 200, response.text
    return response.json()


@pytest.mark.parametrize(
    ("body", "says"),
    [
        ({"gold_pairs": 6}, "gold_pairs"),
        ({"gold_pairs": -1}, "gold_pairs"),
        ({"gold_pairs": False}, "gold_pairs"),
        ({"gold_pairs": "2"}, "gold_pairs"),
        ({"gold_pairs": 2, "gold_gate": 0}, "gold_gate"),
        ({"gold_pairs": 2, "gold_gate": 1.5}, "gold_gate"),
        ({"gold_pairs": 2, "gold_gate": True}, "gold_gate"),
        ({"gold_gate": 0.8}, "set gold_pairs"),
        ({"practice_pairs": 1}, "practice_pairs"),
        ({"practice_pairs": 6}, "practice_pairs"),
        ({"practice_pairs": False}, "practice_pairs"),
    ],
)
def test_bad_quality_settings_are_refused_and_store_nothing(client, experiment, body, says) -> None:
    advised = [r["id"] for r in experiment["runs"] if r["role"] == "advised"]
    baseline = [r["id"] for r in experiment["runs"] if r["role"] == "baseline"]
    before = _count(client)
    for url, extra in (
        (f"/api/experiments/{experiment['id']}/evaluations", {}),
        ("/api/evaluations", {"advised_run_ids": advised, "baseline_run_ids": baseline}),
    ):
        response = client.post(url, json=body | extra, headers=ADMIN)
        assert response.status_code == 422, response.text
        assert says in response.text
    assert _count(client) == before


@pytest.mark.parametrize(
    ("form", "status", "says"),
    [
        ({"gold_pairs": "2", "gold_gate": "0.8", "practice_pairs": "3"}, 303, None),
        ({"gold_pairs": "0", "gold_gate": "0.8"}, 422, "set gold_pairs"),
        ({"gold_pairs": "9"}, 422, "Gold pairs per evaluator"),
        ({"practice_pairs": "1"}, 422, "Practice pairs"),
    ],
)
def test_the_experiment_page_form_takes_the_quality_settings(
    client, experiment, form, status, says
) -> None:
    researcher = logged_in(client)
    token = csrf_token(researcher, f"/experiments/{experiment['id']}")
    body = {"evaluator_kind": "others", "stimulus": "still", "pairs_per_evaluator": "2"}
    before = _count(client)
    response = researcher.post(
        f"/experiments/{experiment['id']}/evaluations", data=body | form | {"csrf_token": token}
    )
    assert response.status_code == status, response.text
    if says is not None:
        assert says in response.text and _count(client) == before
        return
    with client.app.state.runtime.sessions() as session:
        made = session.get(Evaluation, int(response.headers["location"].rsplit("/", 1)[1]))
        assert made is not None
        assert (made.gold_pairs, made.gold_gate, made.practice_pairs) == (2, 0.8, 3)


def _count(client: TestClient) -> int:
    with client.app.state.runtime.sessions() as session:
        return session.scalar(select(func.count()).select_from(Evaluation)) or 0
