"""A lone run takes the second core when the worker allows it (issue 42 §3).

With ``ACV_SPLIT_LONE_RUN`` and one slot, a run that starts while no other run is running
steps half of its envs in a helper process; it writes the same metrics rows as the same run
in one process (bit-identity itself is ``tests/engine/rl/test_env_processes.py``'s). Another
running run, on any worker, keeps a new one in one process. Runs on PostgreSQL.
"""

from __future__ import annotations

import os

import pytest

from app.jobs import queue
from app.jobs.local import LOG_FILE
from app.jobs.settings import JobSettings
from engine.rl.logger import read_metrics
from tests.support.runs import TINY, create_run, get_run, run_app, wait_run
from tests.support.studies import new_study
from tests.support.web import ADMIN

pytestmark = [pytest.mark.training, pytest.mark.postgres_only]
# postgres_only: training is the subject, not storage.

TWO_ENVS = {**TINY, "n_envs": 2, "timesteps": 512}
SPLIT = "its envs step in 2 process(es)"


def _log(settings, run_id: int) -> str:
    return (settings.data_dir / "runs" / str(run_id) / LOG_FILE).read_text()


def _rows(settings, run_id: int) -> list[dict]:
    rows = read_metrics(settings.data_dir / "runs" / str(run_id))
    return [{k: v for k, v in r.items() if k not in ("sps", "time")} for r in rows]


@pytest.fixture(autouse=True)
def two_cpus(monkeypatch: pytest.MonkeyPatch) -> None:
    """The machine the worker sees has 2 CPUs, whatever runs the tests."""
    monkeypatch.setattr(os, "cpu_count", lambda: 2)


def test_a_lone_run_splits_its_envs_and_writes_the_same_rows(settings) -> None:
    with run_app(settings, slots=1, split_lone_run=True) as client:
        study_id = new_study(client)["id"]
        body = {"study_id": study_id, "teacher": "standing", "algo": "ppo", **TWO_ENVS}
        split = create_run(client, seed=7, **body)
        assert wait_run(client, split)["status"] == "succeeded"
    with run_app(settings, slots=1) as client:
        plain = create_run(client, seed=7, **body)
        assert wait_run(client, plain)["status"] == "succeeded"
    assert SPLIT in _log(settings, split) and SPLIT not in _log(settings, plain)
    assert _rows(settings, split) == _rows(settings, plain)


def test_only_a_lone_run_of_a_one_slot_worker_splits(settings) -> None:
    assert JobSettings(split_lone_run=True, worker_slots=1).splits_lone_runs
    assert not JobSettings(split_lone_run=True, worker_slots=2).splits_lone_runs
    assert not JobSettings(worker_slots=1).splits_lone_runs  # off unless asked
    with pytest.MonkeyPatch.context() as one_cpu:
        one_cpu.setattr(os, "cpu_count", lambda: 1)
        assert not JobSettings(split_lone_run=True, worker_slots=1).splits_lone_runs
    with run_app(settings, worker=False) as client:
        study_id = new_study(client)["id"]
        first, second = (
            create_run(
                client, study_id=study_id, teacher="standing", algo="ppo", seed=s, **TWO_ENVS
            )
            for s in (1, 2)
        )
        sessions = client.app.state.runtime.sessions
        with sessions() as session:
            assert queue.running_besides(session, run_id=second) == 0
            claimed = queue.claim_next(session, worker="w", executor="local")
            assert claimed == first
            assert queue.running_besides(session, run_id=second) == 1
            assert queue.running_besides(session, run_id=first) == 0
        client.post(f"/api/runs/{second}/cancel", headers=ADMIN)
        assert get_run(client, second)["status"] == "cancelled"
