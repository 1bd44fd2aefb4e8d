"""Agent evaluations in tests: runs with real (untrained) checkpoints, and the evaluator's
side of the API."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import torch
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session, sessionmaker

from app.core.auth import new_token
from app.db import make_engine, make_sessions
from app.evaluations.service import QUESTIONS
from app.jobs.settings import JobSettings, run_dir
from app.models import (
    Evaluation,
    EvaluationRun,
    EvaluationStimulus,
    Evaluator,
    RunCheckpoint,
    StudyStatus,
)
from app.settings import SQLITE_FILE
from engine.rl.checkpoint import save_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.networks import Agent
from engine.rl.normalize import ObsNormalizer
from tests.support.runs import TINY
from tests.support.wait import wait_for
from tests.support.web import ADMIN

#: The step every test checkpoint is saved at.
STEP = 2048
#: An experiment's runs as tests ask for them (they never train).
EXPERIMENT = {"algo": "bipars-em", "timesteps": 4096, **TINY}


def write_checkpoint(run_folder: Path, *, seed: int, env_id: str = "Hopper-v5") -> Path:
    """An untrained agent's checkpoint (seeded, so runs differ) in ``run_folder``: what
    ``load_agent`` reads, as a run's executor would have saved it."""
    env = gym.make(env_id)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    env.close()
    config = TrainConfig(env_id=env_id, seed=seed)
    torch.manual_seed(seed)
    agent = Agent(obs_dim, act_dim, config.hidden, config.algo, config.z_max, config.z_init)
    state = {
        "config": config.to_json(),
        "obs_dim": obs_dim,
        "act_dim": act_dim,
        "agent": agent.state_dict(),
        "obs_norm": ObsNormalizer((obs_dim,), enabled=config.norm_obs).state_dict(),
        "timesteps": STEP,
    }
    return save_checkpoint(state, run_folder, STEP)


def evaluable_experiment(client: TestClient, study_id: int, *, seeds: int = 2) -> dict[str, Any]:
    """An experiment of ``study_id`` (teacher ``good``) whose advised and baseline runs each
    saved a checkpoint (none trains: the file is written as the executor would write it)."""
    body = {"study_id": study_id, "teacher": "good", "seeds": seeds, **EXPERIMENT}
    response = client.post("/api/experiments", json=body, headers=ADMIN)
    assert response.status_code == 202, response.text
    experiment = response.json()
    runtime = client.app.state.runtime
    save_checkpoints(runtime.sessions, JobSettings().runs_root(runtime.settings), experiment)
    return experiment


def save_checkpoints(
    sessions: sessionmaker[Session], runs_root: Path, experiment: dict[str, Any]
) -> None:
    """A checkpoint for each advised and baseline run of ``experiment`` (its JSON), file and
    row, as the executor would save it (pilots get none)."""
    with sessions() as session:
        for run in experiment["runs"]:
            if run["role"] != "pilot":
                write_checkpoint(run_dir(runs_root, run["id"]), seed=run["id"])
                session.add(RunCheckpoint(run_id=run["id"], step=STEP))
        session.commit()


def save_served_checkpoints(data_dir: Path, experiment: dict[str, Any]) -> None:
    """:func:`save_checkpoints` for a test server's experiment (SQLite in ``data_dir``, its
    runs in ``data_dir/runs``), from outside its process."""
    engine = make_engine(f"sqlite:///{data_dir / SQLITE_FILE}")
    try:
        save_checkpoints(make_sessions(engine), data_dir / "runs", experiment)
    finally:
        engine.dispose()


def wait_evaluation(
    client: TestClient, evaluation_id: int, *, clips: bool = False
) -> dict[str, Any]:
    """The evaluation once it is no longer preparing (and, with ``clips``, once its clips
    are ready or failed)."""

    def probe() -> dict[str, Any]:
        return client.get(f"/api/evaluations/{evaluation_id}", headers=ADMIN).json()

    def ended(found: dict[str, Any]) -> bool:
        settled = not clips or found["clips_ready"] or found["error"] is not None
        return found["status"] != "preparing" and bool(settled)

    return wait_for(probe, ended, what=f"evaluation {evaluation_id} to render", timeout_s=600)


def bare_evaluation(
    client: TestClient, *, run_id: int | None = None, stimulus: str = "still"
) -> int:
    """An evaluation whose rows are written here (nothing renders): with ``run_id``, four
    slots of that run, each with one window whose files do not exist, and ready; else still
    preparing. ``clip``: a clip evaluation whose clips count as rendered, so answers may say
    they saw clips. For tests that need an evaluation to name or join, not to look at."""
    with client.app.state.runtime.sessions() as session, session.begin():
        evaluation = Evaluation(
            name="bare",
            env_id="Hopper-v5",
            evaluator_kind="others",
            question=QUESTIONS["others"],
            instructions="",
            show_bracket=False,
            stimulus=stimulus,
            pairs_per_evaluator=2,
            target_win_rate=0.65,
            seed=0,
            evaluator_counter=0,
            clips_ready=stimulus == "clip",
        )
        session.add(evaluation)
        session.flush()
        if run_id is not None:
            evaluation.status = StudyStatus.READY
            for slot in range(4):
                session.add(
                    EvaluationRun(
                        evaluation_id=evaluation.id,
                        slot=slot,
                        run_id=run_id,
                        advised=slot < 2,
                        step=0,
                    )
                )
                session.add(
                    EvaluationStimulus(
                        evaluation_id=evaluation.id, slot=slot, window=0, still_path="none.jpg"
                    )
                )
        return evaluation.id


def evaluator_headers(client: TestClient) -> dict[str, str]:
    """The bearer header of an evaluator (of a bare evaluation, so with no pairs)."""
    evaluation_id = bare_evaluation(client)
    with client.app.state.runtime.sessions() as session, session.begin():
        person = Evaluator(evaluation_id=evaluation_id, token=new_token(), sequence_index=0)
        session.add(person)
        return {"Authorization": f"Bearer {person.token}"}
