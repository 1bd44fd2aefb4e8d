"""Experiments: advised runs on k seeds and their matched no-advice baseline.

An experiment trains one advice source with one algorithm, env, budget and settings on the
evaluation seeds; its **matched baseline** is ``ppo`` with no advice on the same seeds, env,
budget and settings, and its **pilot** runs are ``ppo`` on seeds of their own, which only pick
the contested matches (docs/method.md §2.11). Baseline and pilot runs are shared: a run of the
same study, config and seed that names advice (so its checkpoints are judged) and is not
failed or cancelled is reused, not trained again, even by two experiments posted at once
(the database keeps one, :mod:`app.runs.shared`).

The verdict is :mod:`app.runs.verdicts`.
"""

from __future__ import annotations

from contextlib import suppress
from dataclasses import dataclass, replace

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, NotFoundError
from app.db import writing
from app.models import Experiment, ExperimentRole, ExperimentRun, Run
from app.runs import service as runs
from app.runs.spec import RunSpec
from engine.errors import InputError

#: Evaluation seeds per arm: the default, and the range the form and API accept.
DEFAULT_SEEDS, MIN_SEEDS, MAX_SEEDS = 5, 2, 20
DEFAULT_PILOT_SEEDS, MAX_PILOT_SEEDS = 2, 10
#: Pilot seeds start here, far from any evaluation seed (those are below it).
PILOT_SEED_BASE = 1_000_000


@dataclass(frozen=True)
class ExperimentSpec:
    """What an experiment trains (``/api/experiments``'s body).

    Attributes:
        run: the advised runs' spec; its ``seed`` is replaced by each evaluation seed.
        seeds: evaluation seeds per arm (``first_seed``, ``first_seed + 1``, ...).
        first_seed: the first evaluation seed.
        pilot_seeds: pilot runs, seeds ``PILOT_SEED_BASE + first_seed + i``.
    """

    run: RunSpec
    seeds: int = DEFAULT_SEEDS
    first_seed: int = 0
    pilot_seeds: int = DEFAULT_PILOT_SEEDS

    def evaluation_seeds(self) -> list[int]:
        return list(range(self.first_seed, self.first_seed + self.seeds))

    def pilot_seed_list(self) -> list[int]:
        start = PILOT_SEED_BASE + self.first_seed
        return list(range(start, start + self.pilot_seeds))


def create_experiment(session: Session, *, spec: ExperimentSpec) -> Experiment:
    """Queue the advised runs, and the baseline and pilot runs not trained already.

    Raises:
        InputError: bad settings (as for a run), a ``ppo`` algo, or seeds out of range.
        NotFoundError, ConflictError: as :func:`app.runs.service.create_run`.
    """
    _check_spec(spec)
    advised: list[Run] = []  # each run commits as it is queued (a baseline may be shared)
    try:
        for seed in spec.evaluation_seeds():
            advised.append(runs.create_run(session, spec=replace(spec.run, seed=seed)))
        baseline = [_baseline_run(session, spec, seed) for seed in spec.evaluation_seeds()]
        pilot = [_baseline_run(session, spec, seed) for seed in spec.pilot_seed_list()]
        return _store(session, spec, advised, baseline, pilot)
    except Exception:
        _cancel(session, advised)
        raise


def _cancel(session: Session, advised: list[Run]) -> None:
    """Cancel the advised runs queued for an experiment that was never made, so none trains
    outside one (the baselines stay: they are shared with any experiment on the settings)."""
    session.rollback()
    for run in advised:
        with suppress(ConflictError):  # ended meanwhile: nothing left to stop
            runs.cancel_run(session, run_id=run.id)


def _store(
    session: Session,
    spec: ExperimentSpec,
    advised: list[Run],
    baseline: list[Run],
    pilot: list[Run],
) -> Experiment:
    """The experiment's row and its members'."""
    experiment = Experiment(
        study_id=spec.run.study_id,
        spec=spec.run.to_request(),
        seeds=spec.evaluation_seeds(),
        pilot_seeds=spec.pilot_seed_list(),
    )
    with writing(session):
        session.add(experiment)
        session.flush()
        for role, members in zip(ExperimentRole, (advised, baseline, pilot), strict=True):
            for run in members:
                session.add(ExperimentRun(experiment_id=experiment.id, run_id=run.id, role=role))
    return experiment


def _check_spec(spec: ExperimentSpec) -> None:
    if spec.run.algo == "ppo":
        raise InputError("an experiment trains with advice: choose an algo other than ppo")
    if not MIN_SEEDS <= spec.seeds <= MAX_SEEDS:
        raise InputError(f"seeds must be in {MIN_SEEDS}..{MAX_SEEDS}, got {spec.seeds}")
    if not 1 <= spec.pilot_seeds <= MAX_PILOT_SEEDS:
        raise InputError(f"pilot_seeds must be in 1..{MAX_PILOT_SEEDS}, got {spec.pilot_seeds}")
    if not 0 <= spec.first_seed < PILOT_SEED_BASE - MAX_SEEDS:
        raise InputError(f"first_seed must be in 0..{PILOT_SEED_BASE - MAX_SEEDS - 1}")


def _baseline_run(session: Session, spec: ExperimentSpec, seed: int) -> Run:
    """The no-advice ``ppo`` run matching ``spec`` at ``seed`` (its config holds a weighted
    pool's weights too): the shared one, else new."""
    return runs.create_run(session, spec=spec.run.baseline(seed), reuse=True)


def get_experiment(session: Session, *, experiment_id: int) -> Experiment:
    experiment = session.get(Experiment, experiment_id)
    if experiment is None:
        raise NotFoundError(f"experiment {experiment_id} not found")
    return experiment


def list_experiments(session: Session, *, study_id: int | None = None) -> list[Experiment]:
    query = select(Experiment).order_by(Experiment.id)
    if study_id is not None:
        query = query.where(Experiment.study_id == study_id)
    return list(session.scalars(query))


def members(session: Session, *, experiment_id: int) -> list[tuple[ExperimentRole, Run]]:
    """``(role, run)`` for every run of the experiment: advised, baseline, pilot, by seed."""
    rows = session.execute(
        select(ExperimentRun.role, Run)
        .join(Run, Run.id == ExperimentRun.run_id)
        .where(ExperimentRun.experiment_id == experiment_id)
    ).all()
    order = list(ExperimentRole)
    return sorted(((role, run) for role, run in rows), key=lambda m: (order.index(m[0]), m[1].seed))


def experiments_of_run(session: Session, *, run_id: int) -> list[int]:
    """The experiments ``run_id`` takes part in."""
    query = select(ExperimentRun.experiment_id).where(ExperimentRun.run_id == run_id)
    return sorted(session.scalars(query))
