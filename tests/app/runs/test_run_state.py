"""Run state in the database (issue 26 §4): the executor stores each update's metrics row and
each saved checkpoint as rows; pages and the API read the rows, never the run folder; runs
from before the rows are imported from their folders once.
"""

from __future__ import annotations

import json
import re
import shutil

import pytest

from app.jobs.backfill import backfill_all
from app.jobs.queue import ours
from app.models import Run, RunCheckpoint, RunMetric
from app.runs import run_state
from app.runtime import Runtime
from app.settings import Settings
from tests.support.runs import TINY, create_run, run_app, wait_run
from tests.support.studies import new_study
from tests.support.web import ADMIN, logged_in


def _run_row(runtime: Runtime, study_id: int, **values: object) -> int:
    """A run row as a worker holds it (``running``, ours), without training."""
    with runtime.sessions() as session:
        run = Run(
            study_id=study_id, algo="ppo", timesteps=1024, seed=0, n_envs=1, config={},
            advice=None, status="running", worker="w1", resume=False, cancel_requested=False,
            **{"progress": 0, **values},
        )  # fmt: skip
        session.add(run)
        session.commit()
        return run.id


def _row(step: int) -> dict[str, object]:
    return {"timesteps": step, "update": step // 128, "episodic_return": float("nan"),
            "episode_returns": [1.0, 2.0]}  # fmt: skip


@pytest.fixture(scope="module")
def ready_study(settings: Settings) -> int:
    with run_app(settings, worker=False) as client:
        return new_study(client)["id"]


def test_an_update_stores_progress_metrics_and_checkpoint_in_one_go(settings, ready_study) -> None:
    runtime = Runtime(settings)
    run_id = _run_row(runtime, ready_study)
    with runtime.sessions() as session:
        for step, saved in ((128, False), (256, True), (384, False)):
            owner = ours(run_id, "w1")
            assert run_state.record_update(
                session, run_id=run_id, owner=owner, row=_row(step), saved=saved
            )
        rows = run_state.metrics_rows(session, run_id=run_id)
        assert [r["timesteps"] for r in rows] == [128, 256, 384]
        assert rows[0]["episodic_return"] is None and "episode_returns" not in rows[0]
        assert run_state.checkpoint_steps(session, run_id=run_id) == [256]
        assert run_state.metrics_rows(session, run_id=run_id, after=256)[0]["timesteps"] == 384
        assert run_state.metrics_rows(session, run_id=run_id, after=10**22) == []  # no overflow
        assert session.get(Run, run_id).progress == 384
    runtime.close()


def test_a_resumed_attempt_replaces_the_rows_it_trains_again(settings, ready_study) -> None:
    runtime = Runtime(settings)
    run_id = _run_row(runtime, ready_study)
    owner = ours(run_id, "w1")
    with runtime.sessions() as session:
        for step in (128, 256, 384, 512):  # the first attempt, killed after 512
            run_state.record_update(
                session, run_id=run_id, owner=owner, row=_row(step), saved=step % 256 == 0
            )
        # resumed from the checkpoint at 256: 384 and 512 are trained again
        run_state.record_update(session, run_id=run_id, owner=owner, row=_row(384), saved=False)
        assert [r["timesteps"] for r in run_state.metrics_rows(session, run_id=run_id)] == [
            128,
            256,
            384,
        ]
        assert run_state.checkpoint_steps(session, run_id=run_id) == [256]
    runtime.close()


def test_an_update_of_a_run_no_longer_ours_stores_nothing(settings, ready_study) -> None:
    runtime = Runtime(settings)
    run_id = _run_row(runtime, ready_study)
    with runtime.sessions() as session:
        owner = ours(run_id, "another worker")
        assert not run_state.record_update(
            session, run_id=run_id, owner=owner, row=_row(128), saved=True
        )
        assert run_state.metrics_rows(session, run_id=run_id) == []
        assert run_state.checkpoint_steps(session, run_id=run_id) == []
    runtime.close()


def test_a_run_from_before_the_rows_is_imported_once(settings, ready_study) -> None:
    """Its folder's metrics and checkpoints become rows; the API then serves them."""
    runtime = Runtime(settings)
    run_id = _run_row(runtime, ready_study, progress=256)
    with runtime.sessions() as session:
        session.get(Run, run_id).status = "succeeded"
        session.commit()
    out = settings.data_dir / "runs" / str(run_id)
    (out / "checkpoints").mkdir(parents=True)
    (out / "checkpoints" / "step_256.pt").write_bytes(b"not read")
    lines = [json.dumps(_row(128)), json.dumps(_row(256)), '{"timesteps": 3']  # cut by a kill
    (out / "metrics.jsonl").write_text("\n".join(lines))
    with runtime.sessions() as session:
        assert run_id in run_state.unimported(session)
    backfill_all(runtime.sessions, runs_root=settings.data_dir / "runs")
    backfill_all(runtime.sessions, runs_root=settings.data_dir / "runs")  # the second: nothing
    with runtime.sessions() as session:
        assert session.query(RunMetric).filter_by(run_id=run_id).count() == 2
        assert session.query(RunCheckpoint).filter_by(run_id=run_id).count() == 1
    runtime.close()
    shutil.rmtree(out)  # from now on only the rows tell
    with run_app(settings, worker=False) as client:
        metrics = client.get(f"/api/runs/{run_id}/metrics", headers=ADMIN).json()
        checkpoints = client.get(f"/api/runs/{run_id}/checkpoints", headers=ADMIN).json()
    assert [m["timesteps"] for m in metrics] == [128, 256]
    assert [c["checkpoint"] for c in checkpoints] == [256]


@pytest.mark.training
def test_pages_and_the_api_serve_a_run_whose_folder_is_gone(settings) -> None:
    """A trained run's metrics, checkpoints and pages come from the rows its executor wrote."""
    with run_app(settings) as client:
        study = new_study(client)
        run_id = create_run(
            client, study_id=study["id"], algo="ppo", timesteps=512, checkpoint_every=256, **TINY
        )
        assert wait_run(client, run_id)["status"] == "succeeded"
        shutil.rmtree(settings.data_dir / "runs" / str(run_id))
        metrics = client.get(f"/api/runs/{run_id}/metrics?after=128", headers=ADMIN).json()
        checkpoints = client.get(f"/api/runs/{run_id}/checkpoints", headers=ADMIN).json()
        page = logged_in(client).get(f"/runs/{run_id}")
    assert [m["timesteps"] for m in metrics] == [256, 384, 512]
    assert [c["checkpoint"] for c in checkpoints] == [256, 512]
    assert checkpoints[1]["metrics"]["timesteps"] == 512
    assert page.status_code == 200
    assert re.findall(r'<li data-step="(\d+)"', page.text) == ["256", "512"]  # from the rows
