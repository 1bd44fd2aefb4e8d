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

from app.models import Evaluation
from tests.support.cli import acv
from tests.support.evaluations import evaluable_experiment
from tests.support.runs import run_app
from tests.support.studies import new_study


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def experiment(client: TestClient) -> dict[str, Any]:
    return evaluable_experiment(client, new_study(client, seed=31)["id"], seeds=2)


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


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (("--advised", "1,x", "--baseline", "2,3"), "whole numbers"),
        ((), "give --experiment"),
        (("--experiment", 999_999), "experiment 999999 not found"),
        (("--experiment", "{experiment}", "--kind", "nobody"), "--kind is"),
        (("--experiment", "{experiment}", "--pairs", 0), "pairs_per_evaluator"),
        (("--experiment", "{experiment}", "--show-bracket"), "advisor only"),
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
