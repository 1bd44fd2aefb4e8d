"""``/api/runs``: the run lifecycle with tiny budgets, the agent's tree and conformance at every
checkpoint (equal to the engine's), exports, cancellation and bad requests.

Runs on PostgreSQL; the app's own local worker executes the runs, two at a time,
each in its own process.
"""

from __future__ import annotations

import csv
import io
import re
import traceback
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import delete
from sqlalchemy.orm import Session, sessionmaker
from typer.testing import Result

from app.core import figures
from app.db import make_engine, make_sessions
from app.models import CheckpointArtefact, Experiment, ExperimentRun
from app.runs import artefacts
from app.runs import report as run_report
from engine.conformance import compare
from engine.judges import JUDGES
from engine.pipeline import replay_with_teacher
from engine.rl.checkpoint import list_checkpoints
from engine.rl.report import checkpoint_report
from engine.treefile import tree_from_json, tree_to_json
from tests.support.cli import acv
from tests.support.runs import (
    ENDLESS,
    TINY,
    create_run,
    finished_participant,
    get_run,
    progressed,
    run_app,
    wait_run,
)
from tests.support.studies import new_study
from tests.support.web import ADMIN

pytestmark = [pytest.mark.training, pytest.mark.postgres_only]
# postgres_only: training is the subject, not storage.

STEPS = [256, 512, 768, 1024]


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client)


@pytest.fixture(scope="module")
def participant(client: TestClient, study: dict[str, Any]) -> int:
    return finished_participant(client, study["id"])


@pytest.fixture(scope="module")
def runs(client: TestClient, study: dict[str, Any], participant: int) -> dict[str, dict]:
    """A ``bipars-em`` run and a ``ppo`` baseline on the same participant's advice, done."""
    advice = {"study_id": study["id"], "participant_id": participant, **TINY}
    ids = {
        "em": create_run(client, algo="bipars-em", timesteps=1024, checkpoint_every=256, **advice),
        "ppo": create_run(client, algo="ppo", timesteps=512, **advice),
    }
    return {name: wait_run(client, run_id) for name, run_id in ids.items()}


def api(client: TestClient, path: str, status: int = 200) -> Any:
    response = client.get(path, headers=ADMIN)
    assert response.status_code == status, response.text
    return response.json() if "json" in response.headers["content-type"] else response


def test_a_run_goes_from_queued_to_succeeded(runs: dict[str, dict], participant: int) -> None:
    run = runs["em"]
    assert run["status"] == "succeeded" and run["error"] is None, run
    assert run["progress"] == {"done": 1024, "total": 1024}
    assert run["executor"] == "local" and run["started_at"] and run["finished_at"]
    assert run["advice"] == f"participant #{participant}" and run["teacher"] is None
    assert run["config"]["checkpoint_every"] == 256 and run["config"]["env_id"] == "Hopper-v5"
    assert run["metrics"]["timesteps"] == 1024 and -2 < run["metrics"]["z_mean"] < 2
    assert "episode_returns" not in run["metrics"]


def test_checkpoints_and_metrics_rows(client: TestClient, runs: dict[str, dict]) -> None:
    run_id = runs["em"]["id"]
    checkpoints = api(client, f"/api/runs/{run_id}/checkpoints")
    assert [c["checkpoint"] for c in checkpoints] == STEPS
    assert all(c["metrics"]["timesteps"] == c["checkpoint"] for c in checkpoints)
    rows = api(client, f"/api/runs/{run_id}/metrics")
    assert [r["timesteps"] for r in rows] == list(range(128, 1025, 128))
    assert [r["timesteps"] for r in api(client, f"/api/runs/{run_id}/metrics?after=768")] == [
        896,
        1024,
    ]


def test_agent_tree_and_conformance_equal_the_engines(
    client: TestClient, runs: dict[str, dict], participant: int
) -> None:
    run_id = runs["em"]["id"]
    human = api(client, f"/api/runs/{run_id}/advice-tree")
    assert human == api(client, f"/api/participants/{participant}/tree")
    latest = api(client, f"/api/runs/{run_id}/agent-tree")
    assert latest == api(client, f"/api/runs/{run_id}/agent-tree?checkpoint=1024")
    agent = tree_from_json(latest)  # a valid acv.tree/1 document over the same bracket
    assert agent.judge == "agent:return@1024"  # the default judge
    expected = compare(tree_from_json(human), agent).to_json()
    assert api(client, f"/api/runs/{run_id}/conformance") == expected
    curve = api(client, f"/api/runs/{run_id}/conformance-curve")
    assert [c["checkpoint"] for c in curve] == STEPS
    for row in curve:
        at = api(client, f"/api/runs/{run_id}/conformance?checkpoint={row['checkpoint']}")
        assert {k: v for k, v in row.items() if k != "checkpoint"} == at


@pytest.mark.parametrize("judge", ["return", "shaping", "shaped-value", "behaviour"])
def test_other_judges_name_themselves(
    client: TestClient, runs: dict[str, dict], judge: str
) -> None:
    doc = api(client, f"/api/runs/{runs['em']['id']}/agent-tree?checkpoint=512&judge={judge}")
    assert doc["judge"] == f"agent:{judge}@512"


def test_value_is_still_read_as_shaped_value(client: TestClient, runs: dict[str, dict]) -> None:
    doc = api(client, f"/api/runs/{runs['em']['id']}/agent-tree?checkpoint=512&judge=value")
    assert doc["judge"] == "agent:shaped-value@512"


def test_ppo_baseline_is_compared_with_the_same_advice(
    client: TestClient, study: dict, runs: dict[str, dict]
) -> None:
    em, ppo = runs["em"], runs["ppo"]
    assert ppo["status"] == "succeeded" and ppo["config"]["checkpoint_every"] == 128
    assert api(client, f"/api/runs/{ppo['id']}/advice-tree") == api(
        client, f"/api/runs/{em['id']}/advice-tree"
    )
    conformance = api(client, f"/api/runs/{ppo['id']}/conformance")
    assert conformance["n_matches"] == 4
    listed = [r["id"] for r in api(client, f"/api/runs?study_id={study['id']}")]
    assert listed.index(ppo["id"]) < listed.index(em["id"])  # newest first


def test_exports(client: TestClient, runs: dict[str, dict]) -> None:
    run_id = runs["em"]["id"]
    svg = api(client, f"/api/runs/{run_id}/trees/human.svg")
    assert svg.headers["content-type"] == "image/svg+xml" and b"<svg" in svg.content
    assert b"data:image/png;base64" in svg.content  # thumbnails are embedded
    png = api(client, f"/api/runs/{run_id}/trees/agent.png?checkpoint=256")
    assert png.content.startswith(b"\x89PNG")
    assert f'filename="run-{run_id}-agent-tree-256.png"' in png.headers["content-disposition"]
    rows = list(
        csv.DictReader(io.StringIO(api(client, f"/api/runs/{run_id}/conformance.csv").text))
    )
    assert [int(r["checkpoint"]) for r in rows] == STEPS
    one = list(
        csv.DictReader(
            io.StringIO(api(client, f"/api/runs/{run_id}/conformance.csv?checkpoint=512").text)
        )
    )
    assert one == [rows[1]]
    report_response = api(client, f"/api/runs/{run_id}/report.html?checkpoint=768")
    policy = report_response.headers["content-security-policy"]
    assert "default-src 'none'" in policy and "frame-ancestors 'none'" in policy
    assert "script-src" not in policy
    report = report_response.text
    assert "<script" not in report and "<link" not in report
    assert not re.search(r'(src|href)="(?!data:|#)', report)  # nothing to fetch
    rejected = api(client, f"/api/runs/{run_id}/conformance?checkpoint=768")["rejected"]
    assert "Overall it kept" in report and "Every judge" in report
    assert report.count('<img src="data:image/jpeg;base64,') == 2 * len(rejected)
    assert bool(rejected) != ("the agent kept every choice" in report)
    assert report.count("<svg") == 4  # two trees and two curves, inline
    assert "Did the advice change the agent?" not in report  # in no experiment


def test_the_report_gives_the_verdict_of_the_runs_experiments(
    client: TestClient, study: dict, runs: dict[str, dict]
) -> None:
    """A run in an experiment: its report says where that experiment's verdict stands (here
    pending: one advised run and one baseline are not enough)."""
    em, ppo = runs["em"]["id"], runs["ppo"]["id"]
    with client.app.state.runtime.sessions() as session, session.begin():
        experiment = Experiment(study_id=study["id"], spec={}, seeds=[0], pilot_seeds=[])
        session.add(experiment)
        session.flush()
        for run_id, role in ((em, "advised"), (ppo, "baseline")):
            session.add(ExperimentRun(experiment_id=experiment.id, run_id=run_id, role=role))
        experiment_id = experiment.id
    report = api(client, f"/api/runs/{em}/report.html?judge=behaviour").text
    assert "Did the advice change the agent?" in report
    assert f"Experiment #{experiment_id}: No verdict yet" in report
    assert "no judge passed ACV's validation" in report  # what the validation found


def test_a_corrupt_thumbnail_is_drawn_without_its_picture(
    client: TestClient, settings, study: dict, runs: dict
) -> None:
    """A thumbnail PIL cannot read (not an image, truncated) leaves its node without a
    picture instead of failing the exports."""
    with client.app.state.runtime.sessions() as session:
        thumbs = run_report.thumb_paths(session, data_dir=settings.data_dir, study_id=study["id"])
    original, run_id = thumbs[0].read_bytes(), runs["em"]["id"]
    try:
        for content in (b"not an image", original[: len(original) // 2]):
            thumbs[0].write_bytes(content)
            assert sorted(figures.load_thumbs(thumbs)) == sorted(set(thumbs) - {0})
            assert b"<svg" in api(client, f"/api/runs/{run_id}/trees/human.svg").content
            assert api(client, f"/api/runs/{run_id}/trees/agent.png").content.startswith(b"\x89PNG")
            assert "Overall it kept" in api(client, f"/api/runs/{run_id}/report.html").text
    finally:
        thumbs[0].write_bytes(original)
    assert sorted(figures.load_thumbs(thumbs)) == sorted(thumbs)


def test_cancel_a_running_teacher_run_then_resume_it(
    client: TestClient, study: dict, participant: int
) -> None:
    run_id = create_run(
        client, study_id=study["id"], teacher="standing", algo="bipars-em", **ENDLESS
    )
    human = api(client, f"/api/runs/{run_id}/advice-tree")
    expected = replay_with_teacher(
        tree_from_json(api(client, f"/api/participants/{participant}/tree")), "standing"
    )
    assert human == tree_to_json(expected)  # the teacher's tree over the study's bracket
    wait_run(client, run_id, progressed)
    cancelled = client.post(f"/api/runs/{run_id}/cancel", headers=ADMIN)
    assert cancelled.status_code == 202 and cancelled.json()["cancel_requested"]
    run = wait_run(client, run_id)
    assert run["status"] == "cancelled" and run["finished_at"], run
    steps = [c["checkpoint"] for c in api(client, f"/api/runs/{run_id}/checkpoints")]
    assert steps[-1] == run["progress"]["done"]  # a stop writes a checkpoint first
    assert client.post(f"/api/runs/{run_id}/cancel", headers=ADMIN).status_code == 409

    resumed = client.post(f"/api/runs/{run_id}/resume", headers=ADMIN)
    # The worker may claim the run before the answer is read back: either state is right.
    assert resumed.status_code == 202 and resumed.json()["status"] in ("queued", "running")
    wait_run(
        client, run_id, lambda r: r["status"] == "running" and r["progress"]["done"] > steps[-1]
    )
    assert client.post(f"/api/runs/{run_id}/cancel", headers=ADMIN).status_code == 202
    assert wait_run(client, run_id)["status"] == "cancelled"


def test_finished_runs_cannot_be_cancelled_or_resumed(
    client: TestClient, runs: dict[str, dict]
) -> None:
    run_id = runs["ppo"]["id"]
    for action in ("cancel", "resume"):
        response = client.post(f"/api/runs/{run_id}/{action}", headers=ADMIN)
        assert response.status_code == 409, response.text
    assert get_run(client, run_id)["status"] == "succeeded"


def test_unknown_checkpoints_and_runs(client: TestClient, runs: dict[str, dict]) -> None:
    run_id = runs["ppo"]["id"]
    response = client.get(f"/api/runs/{run_id}/agent-tree?checkpoint=100", headers=ADMIN)
    assert response.status_code == 422 and "no checkpoint at step 100" in response.json()["detail"]
    assert client.get("/api/runs/999999", headers=ADMIN).status_code == 404
    assert client.get(f"/api/runs/{run_id}").status_code == 401
    assert client.get(f"/api/runs/{run_id}/trees/both.svg", headers=ADMIN).status_code == 422


@pytest.mark.parametrize(
    ("change", "status", "words"),
    [
        ({"teacher": "standing"}, 422, "not both"),
        ({"participant_id": None, "algo": "bipars-em"}, 422, "trains with advice"),
        ({"algo": "sac"}, 422, "algo"),
        ({"participant_id": None, "teacher": "psychic"}, 422, "teacher"),
        ({"timesteps": 0}, 422, "timesteps"),
        ({"n_envs": 1, "num_minibatches": 999}, 422, "num_minibatches"),
        ({"study_id": 999999}, 404, "study 999999"),
        ({"participant_id": 999999}, 404, "participant 999999"),
        ({"unknown": 1}, 422, "unknown"),
    ],
)
def test_bad_run_requests(
    client: TestClient, study: dict, participant: int, change: dict, status: int, words: str
) -> None:
    body = {
        "study_id": study["id"],
        "participant_id": participant,
        "algo": "ppo",
        "timesteps": 1000,
        **change,
    }
    response = client.post("/api/runs", json=body, headers=ADMIN)
    assert response.status_code == status, response.text
    assert words in str(response.json()["detail"])


def test_advice_must_be_finished_and_from_the_study(client: TestClient, study: dict) -> None:
    invited = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    body = {"study_id": study["id"], "participant_id": invited["id"], "timesteps": 1000}
    unfinished = client.post("/api/runs", json=body, headers=ADMIN)
    assert unfinished.status_code == 409 and "not finished" in unfinished.json()["detail"]
    other = new_study(client, seed=4)
    elsewhere = client.post("/api/runs", json=body | {"study_id": other["id"]}, headers=ADMIN)
    assert elsewhere.status_code == 404 and "not in study" in elsewhere.json()["detail"]
    assert client.post("/api/runs", json=body).status_code == 401


def test_a_run_without_advice_has_nothing_to_compare(client: TestClient, study: dict) -> None:
    run_id = create_run(client, study_id=study["id"], algo="ppo", timesteps=256, **TINY)
    assert get_run(client, run_id)["advice"] == "none"
    response = client.get(f"/api/runs/{run_id}/conformance", headers=ADMIN)
    assert response.status_code == 409 and "no advice tree" in response.json()["detail"]
    assert wait_run(client, run_id)["status"] == "succeeded"


def test_the_executor_stores_every_checkpoints_artefact(
    client: TestClient, settings, runs: dict[str, dict]
) -> None:
    run_id = runs["em"]["id"]
    out = settings.data_dir / "runs" / str(run_id)
    assert list(list_checkpoints(out)) == STEPS
    with _sessions(settings) as sessions, sessions() as session:
        stored = artefacts.payloads(session, run_id=run_id)
    assert list(stored) == STEPS and not (out / "agent_trees").exists()
    advice = tree_from_json(api(client, f"/api/runs/{run_id}/advice-tree"))
    fresh = checkpoint_report(out, 512, advice=advice).to_json()
    assert set(stored[512]["judges"]) == set(fresh["judges"]) == set(JUDGES)
    for judge, body in fresh["judges"].items():  # the same verdicts (floats: same to 1e-9)
        kept = stored[512]["judges"][judge]["conformance"]
        assert kept["rejected"] == body["conformance"]["rejected"]
        assert kept["contested"] == body["conformance"]["contested"]
    for row, again in zip(stored[512]["candidates"], fresh["candidates"], strict=True):
        assert row == pytest.approx(again, rel=1e-9)


def test_checkpoint_report_carries_verdict_highlights_judges_and_candidates(
    client: TestClient, runs: dict[str, dict]
) -> None:
    run_id = runs["em"]["id"]
    body = api(client, f"/api/runs/{run_id}/checkpoint-report?checkpoint=768&judge=value")
    m = api(client, f"/api/runs/{run_id}/conformance?checkpoint=768&judge=value")
    assert body["conformance"] == m and body["judge"] == "shaped-value"  # value: the old name
    assert body["highlights"]["agent"] == sorted({r["human_winner"] for r in m["rejected"]})
    assert [j["judge"] for j in body["judges"]] == list(JUDGES)
    contested = m["contested"]
    lead = (
        f"Of the {contested['n']} choices where your advice goes against the environment's "
        f"reward, the agent kept {contested['kept']}."
        if contested["n"]
        else "None of your choices goes against the environment's reward"
    )
    assert body["verdict"].startswith(lead)
    rows = body["candidates"]
    assert [r["id"] for r in rows] == sorted(r["id"] for r in rows) and rows
    assert all(
        r["score"] == r["value"] and r["shaping"] == pytest.approx(r["z"] * r["advice"])
        for r in rows
    )


def test_a_checkpoint_not_judged_yet_is_pending_until_the_backfill(
    client: TestClient, settings, runs: dict[str, dict], monkeypatch: pytest.MonkeyPatch
) -> None:
    run_id = runs["ppo"]["id"]
    before = api(client, f"/api/runs/{run_id}/conformance?checkpoint=256")
    with _sessions(settings) as sessions:
        with sessions() as session:
            session.execute(delete(CheckpointArtefact).where(CheckpointArtefact.run_id == run_id))
            session.commit()
        for path in (
            "conformance?checkpoint=256",
            "agent-tree",
            "checkpoint-report",
            "conformance-curve",
        ):
            assert api(client, f"/api/runs/{run_id}/{path}", 202)["status"] == "pending"
        page = api(client, f"/runs/{run_id}/compare")
        assert page.status_code == 200
    done = _backfill_cli(settings, monkeypatch)
    assert done.exit_code == 0, (done.output, "".join(traceback.format_exception(*done.exc_info)))
    assert int(re.search(r"--backfill: (\d+) checkpoint artefact", done.output)[1]) >= 4
    assert api(client, f"/api/runs/{run_id}/conformance?checkpoint=256") == before
    with _sessions(settings) as sessions:  # nothing left to do
        assert artefacts.backfill(sessions, runs_root=settings.data_dir / "runs") == 0


def _backfill_cli(settings, monkeypatch: pytest.MonkeyPatch) -> Result:
    """``acv worker --backfill`` in-process on this module's database and data dir."""
    monkeypatch.setenv("ACV_DATA_DIR", str(settings.data_dir))
    monkeypatch.setenv("DATABASE_URL", settings.sqlalchemy_url)
    return acv("worker", "--backfill")


@contextmanager
def _sessions(settings) -> Iterator[sessionmaker[Session]]:
    engine = make_engine(settings.sqlalchemy_url)
    try:
        yield make_sessions(engine)
    finally:
        engine.dispose()
