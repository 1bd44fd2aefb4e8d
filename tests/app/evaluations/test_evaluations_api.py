"""Agent evaluations through the API (issue 41): from an experiment to evaluators' answers
and the answer, blind, on both databases.

The runs do not train: each advised and baseline run gets a real (untrained) checkpoint, and
the stimuli are rolled out and rendered for real in the background.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from fastapi.testclient import TestClient
from PIL import Image
from sqlalchemy import update

from app.models import Evaluation
from tests.support.crowd import join
from tests.support.evaluations import evaluable_experiment, wait_evaluation
from tests.support.runs import run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN

# postgres_only: an evaluation's stimuli and answer are the subject, not storage.
pytestmark = pytest.mark.postgres_only


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def experiment(client: TestClient) -> dict[str, Any]:
    study = new_study(client, n_candidates=5, seed=21)
    return evaluable_experiment(client, study["id"], seeds=2)


@pytest.fixture(scope="module")
def evaluation(client: TestClient, experiment: dict[str, Any]) -> dict[str, Any]:
    body = {"pairs_per_evaluator": 6, "stimulus": "clip"}
    response = client.post(
        f"/api/experiments/{experiment['id']}/evaluations", json=body, headers=ADMIN
    )
    assert response.status_code == 201, response.text
    assert response.json()["status"] == "preparing"
    return wait_evaluation(client, response.json()["id"], clips=True)


def _invite(client: TestClient, evaluation_id: int, count: int = 1) -> list[dict[str, Any]]:
    response = client.post(
        f"/api/evaluations/{evaluation_id}/evaluators", json={"count": count}, headers=ADMIN
    )
    assert response.status_code == 201, response.text
    return response.json()


def _bearer(evaluator: dict[str, Any]) -> dict[str, str]:
    return {"Authorization": f"Bearer {evaluator['invite_url'].rsplit('/', 1)[1]}"}


def test_an_experiment_becomes_an_evaluation_with_stills_and_clips(client, evaluation) -> None:
    assert evaluation["status"] == "ready", evaluation
    assert evaluation["clips_ready"] and evaluation["error"] is None
    assert evaluation["question"] == "Which agent follows the instruction better?"
    assert evaluation["evaluator_kind"] == "others"
    # 2 runs per arm: the exact test cannot go below 1/3, so no number of evaluators detects
    assert evaluation["needed_evaluators"] is None and evaluation["design_power"] == 0


def test_an_evaluator_answers_blind_and_the_answer_reads_them(client, evaluation) -> None:
    """Every pair is named by an opaque key only; its pictures decode (a JPEG still, an
    animated WebP clip); after all answers the evaluator is finished, and the result and the
    export count them."""
    (person,) = _invite(client, evaluation["id"])
    headers = _bearer(person)
    run_ids = {str(s["run_id"]) for s in _result(client, evaluation)["slots"]}
    answered = 0
    while (
        response := client.get("/api/evaluators/me/pairs/next", headers=headers)
    ).status_code == 200:
        pair = response.json()
        assert set(pair) == {"key", "position", "total", "question", "left", "right", "reminder"}
        assert pair["reminder"] is None  # an evaluation of others: no bracket reminder
        _pictures_are_blind(client, headers, pair, run_ids)
        choice = "left" if answered % 3 else "tie"
        answer = client.post(
            f"/api/evaluators/me/pairs/{pair['key']}", json={"choice": choice}, headers=headers
        )
        assert answer.status_code == 200, answer.text
        answered += 1
    assert response.status_code == 204 and answered == 6
    me = client.get("/api/evaluators/me", headers=headers).json()
    assert me["finished"] and me["done"] == 6
    result = _result(client, evaluation)
    assert result["n_answers"] == 6 and result["outcome"] in {"cannot_tell", "no_different"}
    rows = list(csv.DictReader(io.StringIO(_csv(client, evaluation))))
    assert len(rows) == 6 and {r["stimulus"] for r in rows} == {"clip"}
    assert sum(r["tie"] == "True" for r in rows) == 2


def _pictures_are_blind(
    client: TestClient, headers: dict[str, str], pair: dict[str, Any], run_ids: set[str]
) -> None:
    for side in ("left", "right"):
        urls = pair[side]
        assert set(urls) == {"still", "clip"}
        for kind, url in urls.items():
            assert pair["key"] in url and not any(f"/{r}/" in url for r in run_ids)
            got = client.get(url, headers=headers)
            assert got.status_code == 200 and "etag" not in got.headers
            image = Image.open(io.BytesIO(got.content))
            assert (image.format, getattr(image, "is_animated", False)) == (
                ("JPEG", False) if kind == "still" else ("WEBP", True)
            )


@contextmanager
def _design_size(client: TestClient, evaluation_id: int, evaluators: int) -> Iterator[None]:
    """The evaluation as if its design had needed ``evaluators`` (put back afterwards)."""

    def set_needed(value: int | None) -> None:
        with client.app.state.runtime.sessions() as session:
            session.execute(
                update(Evaluation)
                .where(Evaluation.id == evaluation_id)
                .values(needed_evaluators=value)
            )
            session.commit()

    with client.app.state.runtime.sessions() as session:
        before = session.get(Evaluation, evaluation_id).needed_evaluators  # type: ignore[union-attr]
    set_needed(evaluators)
    try:
        yield
    finally:
        set_needed(before)


def test_the_answer_is_interim_until_the_designs_evaluators_finish(client, evaluation) -> None:
    """Each look before the planned evaluators have all finished says "interim" in place of
    an outcome; the look once they have gives the outcome in words."""
    assert _result(client, evaluation)["planned_evaluators"] == 100  # no size reaches 80% power
    finished = _result(client, evaluation)["finished_evaluators"]
    (person,) = _invite(client, evaluation["id"])
    headers = _bearer(person)
    with _design_size(client, evaluation["id"], finished + 1):
        for _ in range(evaluation["pairs_per_evaluator"]):
            early = _result(client, evaluation)
            assert not early["final"] and early["sentence"].startswith("Interim: no answer yet")
            assert (early["finished_evaluators"], early["planned_evaluators"]) == (
                finished,
                finished + 1,
            )
            key = client.get("/api/evaluators/me/pairs/next", headers=headers).json()["key"]
            url = f"/api/evaluators/me/pairs/{key}"
            assert client.post(url, json={"choice": "right"}, headers=headers).status_code == 200
        final = _result(client, evaluation)
    assert final["final"] and final["finished_evaluators"] == finished + 1
    assert not final["sentence"].startswith("Interim") and "agent trained with" in final["sentence"]


def test_an_answer_is_written_once(client, evaluation) -> None:
    (person,) = _invite(client, evaluation["id"])
    headers = _bearer(person)
    key = client.get("/api/evaluators/me/pairs/next", headers=headers).json()["key"]
    url = f"/api/evaluators/me/pairs/{key}"
    assert client.post(url, json={"choice": "left"}, headers=headers).status_code == 200
    assert client.post(url, json={"choice": "left"}, headers=headers).status_code == 200
    again = client.post(url, json={"choice": "right"}, headers=headers)
    assert again.status_code == 409 and "already answered" in again.json()["detail"]


def test_a_pair_is_nobody_elses(client, evaluation) -> None:
    first, second = _invite(client, evaluation["id"], count=2)
    key = client.get("/api/evaluators/me/pairs/next", headers=_bearer(first)).json()["key"]
    for url in (f"/api/evaluators/me/pairs/{key}/left/still",):
        assert client.get(url, headers=_bearer(second)).status_code == 404
    post = client.post(
        f"/api/evaluators/me/pairs/{key}", json={"choice": "left"}, headers=_bearer(second)
    )
    assert post.status_code == 404


@pytest.mark.parametrize(
    "body",
    [
        {"choice": "up"},
        {"choice": "left", "response_ms": True},
        {"choice": "left", "response_ms": -1},
        {"choice": "left", "extra": 1},
        {},
    ],
)
def test_bad_answers_are_422(client, evaluation, body) -> None:
    (person,) = _invite(client, evaluation["id"])
    headers = _bearer(person)
    key = client.get("/api/evaluators/me/pairs/next", headers=headers).json()["key"]
    response = client.post(f"/api/evaluators/me/pairs/{key}", json=body, headers=headers)
    assert response.status_code == 422, response.text


@pytest.mark.parametrize(
    ("body", "status", "says"),
    [
        ({"pairs_per_evaluator": 0}, 422, "pairs_per_evaluator"),
        ({"pairs_per_evaluator": True}, 422, "pairs_per_evaluator"),
        ({"target_win_rate": 0.5}, 422, "target_win_rate"),
        ({"evaluator_kind": "advisor"}, 409, "one participant's tree"),
        ({"evaluator_kind": "advisor", "show_bracket": True}, 409, "one participant's tree"),
        ({"show_bracket": True}, 422, "advisor only"),
        ({"show_bracket": "true"}, 422, "show_bracket"),
        ({"stimulus": "video"}, 422, "stimulus"),
    ],
)
def test_bad_evaluations_are_refused(client, experiment, body, status, says) -> None:
    response = client.post(
        f"/api/experiments/{experiment['id']}/evaluations", json=body, headers=ADMIN
    )
    assert response.status_code == status, response.text
    assert says in response.text


def test_runs_without_checkpoints_or_too_few_are_refused(client, experiment) -> None:
    pilot = next(r["id"] for r in experiment["runs"] if r["role"] == "pilot")
    advised = [r["id"] for r in experiment["runs"] if r["role"] == "advised"]
    baseline = [r["id"] for r in experiment["runs"] if r["role"] == "baseline"]
    cases = [
        ({"advised_run_ids": advised, "baseline_run_ids": [baseline[0], pilot]}, 409),
        ({"advised_run_ids": advised, "baseline_run_ids": baseline[:1]}, 422),
        ({"advised_run_ids": advised, "baseline_run_ids": [999_999, baseline[0]]}, 404),
        ({"advised_run_ids": advised, "baseline_run_ids": advised}, 422),
    ]
    for body, status in cases:
        response = client.post("/api/evaluations", json=body, headers=ADMIN)
        assert response.status_code == status, (body, response.text)


def _result(client: TestClient, evaluation: dict[str, Any]) -> dict[str, Any]:
    response = client.get(f"/api/evaluations/{evaluation['id']}/result", headers=ADMIN)
    assert response.status_code == 200, response.text
    return response.json()


def _csv(client: TestClient, evaluation: dict[str, Any]) -> str:
    response = client.get(f"/api/evaluations/{evaluation['id']}/answers.csv", headers=ADMIN)
    assert response.status_code == 200, response.text
    return response.text


def _join(client: TestClient, slug: str, pid: str) -> dict[str, str]:
    """A visitor through the open link: the bearer header of the evaluator they became."""
    visit = TestClient(client.app, follow_redirects=False)
    response = join(visit, f"/e/{slug}", params={"PROLIFIC_PID": pid})
    assert response.status_code in (302, 303) and response.headers["location"] == "/evaluate"
    return {"Authorization": f"Bearer {response.cookies['acv_evaluator']}"}


def test_the_open_link_admits_evaluators_with_codes_and_withdrawal(client, evaluation) -> None:
    """An evaluator who joins through ``/e/<slug>`` and answers every pair gets the
    completion code; one who withdraws gets the decline code, can answer no more, and their
    answers are left out of the result and the export."""
    link = client.put(
        f"/api/evaluations/{evaluation['id']}/crowd",
        headers=ADMIN,
        json={
            "enabled": True,
            "max_participants": 10,
            "completion_code": "DONE-1",
            "decline_code": "LEFT-1",
            "time_limit_min": 60,
        },
    )
    assert link.status_code == 200 and link.json()["url"].endswith(f"/e/{link.json()['slug']}")
    finisher = _join(client, link.json()["slug"], "p-finisher")
    while (
        pair := client.get("/api/evaluators/me/pairs/next", headers=finisher)
    ).status_code == 200:
        url = f"/api/evaluators/me/pairs/{pair.json()['key']}"
        assert client.post(url, json={"choice": "right"}, headers=finisher).status_code == 200
    me = client.get("/api/evaluators/me", headers=finisher).json()
    assert (me["outcome"], me["code"]) == ("finished", "DONE-1")
    before = _result(client, evaluation)["n_answers"]
    leaver = _join(client, link.json()["slug"], "p-leaver")
    key = client.get("/api/evaluators/me/pairs/next", headers=leaver).json()["key"]
    url = f"/api/evaluators/me/pairs/{key}"
    assert client.post(url, json={"choice": "left"}, headers=leaver).status_code == 200
    assert _result(client, evaluation)["n_answers"] == before + 1
    unanswered = client.get("/api/evaluators/me/pairs/next", headers=leaver).json()["key"]
    left = client.post("/api/evaluators/me/withdraw", json={"withdraw": True}, headers=leaver)
    assert left.status_code == 200 and left.json()["code"] == "LEFT-1"
    assert _result(client, evaluation)["n_answers"] == before
    assert client.get("/api/evaluators/me", headers=leaver).json()["outcome"] == "withdrawn"
    late = f"/api/evaluators/me/pairs/{unanswered}"
    assert client.post(late, json={"choice": "left"}, headers=leaver).status_code == 410
    assert client.get("/api/evaluators/me/pairs/next", headers=leaver).status_code == 410
