"""``acv evaluate``: an evaluation from an experiment, its evaluators and its answer from the
command line (issue 41), the same services as the API; bad input is one line on stderr and
exit code 2, with nothing stored."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from click.testing import Result
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from app.evaluations.service import QUESTIONS
from app.jobs.settings import JobSettings
from app.models import Evaluation
from tests.support.cli import acv
from tests.support.evaluations import EXPERIMENT, evaluable_experiment, save_checkpoints
from tests.support.runs import run_app
from tests.support.studies import new_study
from tests.support.surveys import finished
from tests.support.web import ADMIN

# postgres_only: an evaluation's stimuli and answer are the subject, not storage.
pytestmark = pytest.mark.postgres_only


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def experiment(client: TestClient) -> dict[str, Any]:
    return evaluable_experiment(client, new_study(client, seed=31)["id"], seeds=2)


@pytest.fixture(scope="module")
def advised_by_one(client: TestClient) -> tuple[dict[str, Any], int]:
    """An experiment whose advised runs train on one finished participant's tree, and that
    participant: as :func:`evaluable_experiment`, each advised and baseline run with a saved
    checkpoint (none trains). Its own study, so no baseline run is shared with ``experiment``."""
    study_id = new_study(client, seed=32)["id"]
    person = finished(client, study_id)
    body = {"study_id": study_id, "participant_id": person, "seeds": 2, **EXPERIMENT}
    response = client.post("/api/experiments", json=body, headers=ADMIN)
    assert response.status_code == 202, response.text
    experiment = response.json()
    runtime = client.app.state.runtime
    save_checkpoints(runtime.sessions, JobSettings().runs_root(runtime.settings), experiment)
    return experiment, person


@pytest.fixture
def run(settings, monkeypatch: pytest.MonkeyPatch) -> Callable[..., Result]:
    """``acv`` in this process, on this module's database and data dir."""
    monkeypatch.setenv("ACV_DATA_DIR", str(settings.data_dir))
    monkeypatch.setenv("DATABASE_URL", settings.sqlalchemy_url)
    return acv


def test_create_invite_and_read_the_answer(run, experiment) -> None:
    created = run("evaluate", "create", "--experiment", experiment["id"], "--stimulus", "still")
    assert created.exit_code == 0, created.output
    evaluation_id = int(created.output.split()[1].rstrip(":"))
    assert created.output.strip().endswith("ready")
    invited = run("evaluate", "invite", "--evaluation", evaluation_id, "--count", 2)
    assert invited.exit_code == 0, invited.output
    links = invited.output.split()
    assert len(links) == 2 and all("/v/" in link for link in links)
    answer = run("evaluate", "result", "--evaluation", evaluation_id, "--json")
    assert answer.exit_code == 0, answer.output
    body = json.loads(answer.output)
    assert body["outcome"] == "cannot_tell" and body["n_answers"] == 0
    listed = run("evaluate", "list")
    assert f"{evaluation_id}\tready" in listed.output


def test_the_advisor_may_be_shown_their_bracket(run, client, advised_by_one) -> None:
    """``--show-bracket`` with ``--kind advisor`` (refused for ``others`` below): stored on."""
    experiment, person = advised_by_one
    before = _evaluations(client)
    created = run(
        "evaluate", "create", "--experiment", experiment["id"], "--kind", "advisor",
        "--show-bracket", "--stimulus", "still",
    )  # fmt: skip
    assert created.exit_code == 0, created.output
    evaluation_id = int(created.output.split()[1].rstrip(":"))
    assert created.output.strip().endswith("ready")
    assert _evaluations(client) == before + 1
    with client.app.state.runtime.sessions() as session:
        stored = session.get(Evaluation, evaluation_id)
        assert stored is not None
        assert stored.show_bracket is True
        assert stored.evaluator_kind == "advisor" and stored.advisor_id == person
        assert stored.question == QUESTIONS["advisor"]
        assert stored.experiment_id == experiment["id"]
    shown = client.get(f"/api/evaluations/{evaluation_id}", headers=ADMIN).json()
    assert shown["show_bracket"] is True and shown["evaluator_kind"] == "advisor"


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (("--advised", "1,x", "--baseline", "2,3"), "whole numbers"),
        (("--advised", "1_0,2", "--baseline", "3,4"), "whole numbers"),  # int() reads 10
        ((), "give --experiment"),
        (("--advised", "1,2"), "with --baseline"),
        (("--experiment", "{experiment}", "--baseline", "3,4"), "not both"),
        (("--experiment", 999_999), "experiment 999999 not found"),
        (("--experiment", "{experiment}", "--kind", "nobody"), "--kind is"),
        (("--experiment", "{experiment}", "--pairs", 0), "pairs_per_evaluator"),
        (("--experiment", "{experiment}", "--show-bracket"), "advisor only"),
        (("--experiment", "{experiment}", "--gold-pairs", 6), "gold_pairs"),
        (("--experiment", "{experiment}", "--gold-gate", 0.8), "set gold_pairs"),
        (("--experiment", "{experiment}", "--gold-pairs", 2, "--gold-gate", 1.5), "gold_gate"),
        (("--experiment", "{experiment}", "--practice-pairs", 1), "practice_pairs"),
    ],
)
def test_bad_input_is_exit_2_and_stores_nothing(run, client, experiment, args, says) -> None:
    before = _evaluations(client)
    filled = [str(a).format(experiment=experiment["id"]) for a in args]
    result = run("evaluate", "create", *filled)
    assert result.exit_code == 2, result.output
    assert says in result.output and "Traceback" not in result.output
    assert _evaluations(client) == before


def _evaluations(client: TestClient) -> int:
    with client.app.state.runtime.sessions() as session:
        return session.scalar(select(func.count()).select_from(Evaluation)) or 0
