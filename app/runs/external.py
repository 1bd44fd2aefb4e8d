"""External experiments (issue 44 §2): the verdict on policies trained anywhere.

An external experiment names a study and an advice source, as ACV's own experiments do, but
trains nothing: its runs are policies imported afterwards (:mod:`app.runs.agent_import`),
*advised* (trained with the advice, e.g. through ACV's Gymnasium wrapper), *baseline* (the same
training without it) and *pilot* (more no-advice policies, on seeds of their own, that only
pick the contested matches), up to ``seeds_per_arm`` seeds each (pilots: up to
:data:`~app.runs.experiments.MAX_PILOT_SEEDS`). The advice tree is frozen when the experiment
is created, with its hash (:func:`app.runs.imported.tree_digest`), which the people training
compare with the one their wrapper used. The env's observation and action sizes are read once
here, so that an upload is checked without building the env.

The experiment's ``spec`` is ``{"external": true, "study_id", <advice fields>, "env_id",
"obs_dim", "act_dim", "seeds_per_arm", "tree_sha256", "frozen": {...}}``; its ``seeds`` and
``pilot_seeds`` list the seeds imported so far.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

from sqlalchemy.orm import Session

from app.core.errors import ConflictError
from app.db import writing
from app.models import Experiment, ExperimentRole
from app.runs import advice, experiments, pools, service
from app.runs.experiments import DEFAULT_SEEDS, MAX_SEEDS, MIN_SEEDS, get_experiment
from app.runs.imported import EXTERNAL, FROZEN, is_external, tree_digest
from app.runs.spec import AdviceSource, advice_fields
from app.studies.service import get_ready_study
from engine.envs import env_dims
from engine.errors import InputError
from engine.treefile import TreeDocument, tree_from_json, tree_to_json


@dataclass(frozen=True)
class ExternalSpec:
    """An external experiment to create.

    Attributes:
        study_id: the study whose bracket the advice is over (and whose env the policies act in).
        advice: the advice the advised policies trained with (required).
        seeds_per_arm: the most advised and the most baseline policies it takes.
    """

    study_id: int
    advice: AdviceSource
    seeds_per_arm: int = DEFAULT_SEEDS


@dataclass(frozen=True)
class ExternalInfo:
    """What an upload to an external experiment is checked against, and what its runs take.

    Attributes:
        env_id: the study's env.
        obs_dim: its observation size.
        act_dim: its action size.
        seeds_per_arm: the most policies of the advised arm, and of the baseline arm.
        tree: the frozen advice tree (``acv.tree/1`` JSON).
        tree_sha256: its hash.
        advice_pool: a pool's members (``runs.advice_pool``), else None.
        pool_weights: a reliability-weighted pool's weights, else None.
        participant_id: the participant whose tree it is, else None.
        teacher: the teacher whose tree it is, else None.
    """

    env_id: str
    obs_dim: int
    act_dim: int
    seeds_per_arm: int
    tree: dict[str, Any]
    tree_sha256: str
    advice_pool: list[dict[str, Any]] | None
    pool_weights: list[float] | None
    participant_id: int | None
    teacher: str | None


@functools.cache
def env_sizes(env_id: str) -> tuple[int, int]:
    """The env's observation and action sizes (the env is built once per process)."""
    return env_dims(env_id)


def create_external_experiment(session: Session, *, spec: ExternalSpec) -> Experiment:
    """Store an external experiment with its frozen advice; nothing is queued.

    Raises:
        InputError: no advice, a bad pool or teacher, or seeds out of range.
        NotFoundError, ConflictError: no such study or participant, a study not ready, a
            participant not finished or excluded (as for a run).
    """
    if spec.advice is None:
        raise InputError(
            "an external experiment compares policies trained with advice and without: give "
            "participant_id, participant_ids (or all_participants) or teacher"
        )
    if not MIN_SEEDS <= spec.seeds_per_arm <= MAX_SEEDS:
        raise InputError(f"seeds must be in {MIN_SEEDS}..{MAX_SEEDS}, got {spec.seeds_per_arm}")
    study = get_ready_study(session, study_id=spec.study_id)
    pooled, tree = advice.resolve(session, spec.advice, study_id=spec.study_id)
    if tree is None:  # resolve gives a tree for every advice source
        raise InputError("the advice source gives no tree")
    obs_dim, act_dim = env_sizes(study.env_id)
    weights = None if pooled is None or pooled.weights is None else list(pooled.weights)
    frozen = {
        "advice": tree_to_json(tree),
        "advice_pool": None if pooled is None else pooled.members,
        "pool_weights": weights,
    }
    experiment = Experiment(
        study_id=spec.study_id,
        spec={
            EXTERNAL: True,
            "study_id": spec.study_id,
            **advice_fields(spec.advice),
            "env_id": study.env_id,
            "obs_dim": obs_dim,
            "act_dim": act_dim,
            "seeds_per_arm": spec.seeds_per_arm,
            "tree_sha256": tree_digest(tree),
            FROZEN: frozen,
        },
        seeds=[],
        pilot_seeds=[],
    )
    with writing(session):
        session.add(experiment)
    return experiment


def external_info(experiment: Experiment) -> ExternalInfo:
    """What an external experiment's uploads are checked against.

    Raises:
        InputError: not an external experiment.
    """
    if not is_external(experiment):
        raise InputError(f"experiment {experiment.id} is not external")
    spec = experiment.spec
    frozen = spec[FROZEN]
    return ExternalInfo(
        env_id=spec["env_id"],
        obs_dim=int(spec["obs_dim"]),
        act_dim=int(spec["act_dim"]),
        seeds_per_arm=int(spec["seeds_per_arm"]),
        tree=frozen["advice"],
        tree_sha256=spec["tree_sha256"],
        advice_pool=frozen.get("advice_pool"),
        pool_weights=frozen.get("pool_weights"),
        participant_id=spec.get("participant_id"),
        teacher=spec.get("teacher"),
    )


def external_experiment(session: Session, *, experiment_id: int) -> ExternalInfo:
    """:func:`external_info` of experiment ``experiment_id``.

    Raises:
        NotFoundError: no such experiment.
        InputError: it trains its own runs.
    """
    return external_info(get_experiment(session, experiment_id=experiment_id))


def advice_tree(experiment: Experiment) -> TreeDocument:
    """An external experiment's frozen advice tree."""
    return tree_from_json(external_info(experiment).tree)


def advice_label(experiment: Experiment) -> str:
    """Who gave an external experiment's advice, as :func:`app.runs.service.advice_label`
    says it of a run."""
    info = external_info(experiment)
    if info.advice_pool:
        ids = [int(m["participant_id"]) for m in info.advice_pool]
        return pools.pool_label(ids, weighted=info.pool_weights is not None)
    if info.participant_id is not None:
        return f"participant #{info.participant_id}"
    return f"teacher {info.teacher}"


def experiment_advice(session: Session, *, experiment_id: int) -> TreeDocument:
    """The advice tree an experiment's advised policies train with: an external one's frozen
    tree, else its advised runs' (as ``GET /api/runs/{id}/advice-tree`` reads a run's).

    Raises:
        NotFoundError: no such experiment.
        ConflictError: its advised runs have no advice tree.
    """
    experiment = get_experiment(session, experiment_id=experiment_id)
    if is_external(experiment):
        return advice_tree(experiment)
    members = experiments.members(session, experiment_id=experiment_id)
    advised = next((run for role, run in members if role == ExperimentRole.ADVISED), None)
    if advised is None:
        raise ConflictError(f"experiment {experiment_id} has no advised runs")
    return service.advice_of(advised)
