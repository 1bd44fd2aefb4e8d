"""Helpers of the training-run tests: an app with a fast worker, tiny budgets, waiting."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from fastapi.testclient import TestClient

from app.jobs.settings import JobSettings
from app.main import create_app
from app.settings import Settings
from tests.support.studies import Player
from tests.support.wait import wait_for
from tests.support.web import ADMIN

#: A tiny PPO budget on the 5-candidate Hopper study: 128 steps per update.
TINY = {"n_envs": 1, "num_steps": 128, "num_minibatches": 4, "update_epochs": 2}
#: A run that would take hours: tests stop it (cancel, kill, restart) once it has progressed.
ENDLESS = {**TINY, "timesteps": 10_000_000, "checkpoint_every": 256}
FINAL = ("succeeded", "failed", "cancelled", "interrupted")


@contextmanager
def run_app(
    settings: Settings, *, worker: bool = True, slots: int = 2, **job_settings: Any
) -> Iterator[TestClient]:
    """The app with its lifespan running; its run worker polls every 0.1 s and, unless
    ``backfill_s`` is given, never backfills (tests that delete artefacts expect them gone)."""
    app = create_app(settings)
    app.state.job_settings = JobSettings(
        run_worker=worker, worker_slots=slots, poll_s=0.1, **{"backfill_s": 0, **job_settings}
    )
    with TestClient(app) as client:
        yield client


def create_run(client: TestClient, **body: Any) -> int:
    response = client.post("/api/runs", json=body, headers=ADMIN)
    assert response.status_code == 202, response.text
    # A worker may claim the run between its commit and the answer's read: either state.
    assert response.json()["status"] in ("queued", "running")
    return response.json()["id"]


def get_run(client: TestClient, run_id: int) -> dict[str, Any]:
    response = client.get(f"/api/runs/{run_id}", headers=ADMIN)
    assert response.status_code == 200, response.text
    return response.json()


def wait_run(
    client: TestClient,
    run_id: int,
    until: Callable[[dict[str, Any]], bool] = lambda r: r["status"] in FINAL,
    timeout_s: float = 180.0,
) -> dict[str, Any]:
    """Poll a run until ``until`` holds (by default: it has ended); returns its JSON."""
    return wait_for(
        lambda: get_run(client, run_id), until, what=f"run {run_id}", timeout_s=timeout_s
    )


def progressed(run: dict[str, Any]) -> bool:
    """Running, past its first checkpoint (256 steps in :data:`ENDLESS`)."""
    assert run["status"] in ("queued", "running"), run
    return run["status"] == "running" and run["progress"]["done"] >= 256


def finished_participant(client: TestClient, study_id: int) -> int:
    """A participant of ``study_id`` who has labelled the whole bracket (always side a)."""
    response = client.post(f"/api/studies/{study_id}/participants", headers=ADMIN)
    assert response.status_code == 201, response.text
    body = response.json()
    Player(client, body["id"], body["token"], body["invite_url"]).play()
    return body["id"]
