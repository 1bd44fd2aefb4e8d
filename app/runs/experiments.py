"""Experiments: advised runs on k seeds, their matched no-advice baseline, and the verdict.

An experiment trains one advice source with one algorithm, env, budget and settings on the
evaluation seeds; its **matched baseline** is ``ppo`` with no advice on the same seeds, env,
budget and settings, and its **pilot** runs are ``ppo`` on seeds of their own, which only pick
the contested matches (docs/method.md §2.11). Baseline and pilot runs are shared: a run of the
same study, config and seed that names advice (so its checkpoints are judged) and is not
failed or cancelled is reused, not trained again, even by two experiments posted at once
(the database keeps one, :mod:`app.runs.shared`).

The verdict reads the runs' stored checkpoint artefacts (the per-candidate table that each
run's executor writes) and hands them to :func:`engine.verdict_outcome.verdict`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.db import writing
from app.labelling import disagreement
from app.models import (
    CheckpointArtefact,
    Experiment,
    ExperimentRole,
    ExperimentRun,
    Run,
    RunCheckpoint,
)
from app.runs import artefacts
from app.runs import service as runs
from app.runs.imported import is_external, latest_only
from app.runs.spec import RunSpec
from engine.errors import InputError
from engine.judges import JUDGE_COLUMNS, VERDICT_JUDGES, judge_name
from engine.treefile import TreeDocument, tree_from_json
from engine.verdict import Pair, Verdict, VerdictInputs, advice_scores, bracket_pairs
from engine.verdict_outcome import verdict

#: Evaluation seeds per arm: the default, and the range the form and API accept.
DEFAULT_SEEDS, MIN_SEEDS, MAX_SEEDS = 5, 2, 20
DEFAULT_PILOT_SEEDS, MAX_PILOT_SEEDS = 2, 10
#: Pilot seeds start here, far from any evaluation seed (those are below it).
PILOT_SEED_BASE = 1_000_000
#: Fewest runs per role with a judged checkpoint before a verdict is attempted.
#: role -> run id -> step -> the per-candidate rows of that judged checkpoint.
JudgedTables = dict[ExperimentRole, dict[int, dict[int, list[dict[str, Any]]]]]

MIN_JUDGED = {ExperimentRole.ADVISED: 2, ExperimentRole.BASELINE: 2, ExperimentRole.PILOT: 1}


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


@dataclass(frozen=True)
class ExperimentVerdict:
    """The verdict of one judge at one checkpoint step, and the runs it rests on."""

    judge: str
    step: int
    verdict: Verdict
    runs: dict[ExperimentRole, list[int]] = field(default_factory=dict)


def create_experiment(session: Session, *, spec: ExperimentSpec) -> Experiment:
    """Queue the advised runs, and the baseline and pilot runs not trained already.

    Raises:
        InputError: bad settings (as for a run), a ``ppo`` algo, or seeds out of range.
        NotFoundError, ConflictError: as :func:`app.runs.service.create_run`.
    """
    _check_spec(spec)
    advised = [
        runs.create_run(session, spec=replace(spec.run, seed=seed))
        for seed in spec.evaluation_seeds()
    ]
    baseline = [_baseline_run(session, spec, seed) for seed in spec.evaluation_seeds()]
    pilot = [_baseline_run(session, spec, seed) for seed in spec.pilot_seed_list()]
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


def experiment_verdict(
    session: Session, *, experiment_id: int, judge: str, step: int | None = None
) -> ExperimentVerdict | None:
    """The verdict of ``judge`` at ``step`` (default: the latest step judged in enough runs
    of every role, :data:`MIN_JUDGED`; for an external experiment, each run's own checkpoint,
    reported as the largest of their steps); None while no such step exists yet.

    Raises:
        NotFoundError: no such experiment, or ``step`` is no checkpoint of its runs.
        InputError: a judge the runs' artefacts do not score (an external experiment's:
            any but the verdict judges).
    """
    experiment = get_experiment(session, experiment_id=experiment_id)
    external = is_external(experiment)
    if external and judge_name(judge) not in VERDICT_JUDGES:
        raise InputError(f"imported policies are judged by {' or '.join(VERDICT_JUDGES)} only")
    runs_ = members(session, experiment_id=experiment_id)
    if step is not None:
        _check_step(session, experiment_id, [run.id for _, run in runs_], step)
    judged = _judged_tables(session, runs_)
    if external and step is None:  # one checkpoint each, at the steps their trainers declare
        judged = latest_only(judged)
    step = _verdict_step(judged) if step is None else step
    if step is None:
        return None
    table = {
        role: {rid: t[step] for rid, t in by_run.items() if step in t}
        for role, by_run in judged.items()
    }
    if any(len(table[role]) < n for role, n in MIN_JUDGED.items()):
        return None
    advice = _advice_of(session, experiment)
    arrays = {role: _scores(list(rows.values()), judge) for role, rows in table.items()}
    inputs = VerdictInputs(
        advice=advice_scores(advice),
        advised=arrays[ExperimentRole.ADVISED],
        baseline=arrays[ExperimentRole.BASELINE],
        pilot=arrays[ExperimentRole.PILOT],
        matches=bracket_pairs(advice) + _pairs_of(session, experiment),
        reward=np.array([c.env_reward for c in advice.candidates]),
    )
    result = verdict(inputs, np.random.default_rng([experiment.id, step]))
    used = {role: list(rows) for role, rows in table.items()}  # in the arrays' order
    return ExperimentVerdict(judge=judge, step=step, verdict=result, runs=used)


def _check_step(session: Session, experiment_id: int, run_ids: list[int], step: int) -> None:
    """:class:`NotFoundError` unless a run of the experiment saved a checkpoint at ``step``
    (judged or not yet); compared here, not in SQL, where any int may be asked."""
    saved = select(RunCheckpoint.step).where(RunCheckpoint.run_id.in_(run_ids))
    stored = select(CheckpointArtefact.step).where(CheckpointArtefact.run_id.in_(run_ids))
    steps = set(session.scalars(saved.union(stored)))
    if step not in steps:
        latest = f"; the latest is step {max(steps)}" if steps else "; they have none yet"
        raise NotFoundError(
            f"experiment {experiment_id}'s runs have no checkpoint at step {step}{latest}"
        )


def _judged_tables(session: Session, members_: list[tuple[ExperimentRole, Run]]) -> JudgedTables:
    """role -> run id -> step -> the per-candidate rows of that judged checkpoint."""
    tables: JudgedTables = {role: {} for role in ExperimentRole}
    for role, run in members_:
        bodies = artefacts.payloads(session, run_id=run.id)
        tables[role][run.id] = {
            step: body["candidates"] for step, body in bodies.items() if artefacts.judged(body)
        }
    return tables


def _verdict_step(judged: JudgedTables) -> int | None:
    """The latest step judged in at least :data:`MIN_JUDGED` runs of every role."""
    steps: set[int] | None = None
    for role, needed in MIN_JUDGED.items():
        counts: dict[int, int] = {}
        for by_step in judged[role].values():
            for step in by_step:
                counts[step] = counts.get(step, 0) + 1
        enough = {step for step, n in counts.items() if n >= needed}
        steps = enough if steps is None else steps & enough
    return max(steps) if steps else None


def _scores(tables: list[list[dict[str, Any]]], judge: str) -> np.ndarray:
    """The judge's score per run and candidate, shape ``(runs, N)``.

    Raises:
        InputError: not a judge, or checkpoints judged without it (before it existed).
    """
    column = JUDGE_COLUMNS[judge_name(judge)]
    scores = [[row.get(column) for row in sorted(t, key=lambda r: r["id"])] for t in tables]
    if any(s is None for run in scores for s in run):
        raise InputError(
            f"these runs' checkpoints were judged without the {judge!r} judge: choose another"
        )
    return np.array(scores, dtype=float)


def _advised_run(session: Session, experiment: Experiment) -> Run:
    """The experiment's first advised run.

    Raises:
        InputError: it has none (the API never makes such an experiment).
    """
    found = members(session, experiment_id=experiment.id)
    run = next((r for role, r in found if role == ExperimentRole.ADVISED), None)
    if run is None:
        raise InputError(f"experiment {experiment.id} has no advised runs")
    return run


def _pairs_of(session: Session, experiment: Experiment) -> tuple[Pair, ...]:
    """The answered disagreement pairs of the participant whose advice the runs take (none
    for a teacher's or pooled advice): the verdict counts them as matches of the advice."""
    advised = _advised_run(session, experiment)
    if advised.participant_id is None or advised.advice_pool:
        return ()
    return disagreement.answered(session, participant_id=advised.participant_id)


def _advice_of(session: Session, experiment: Experiment) -> TreeDocument:
    """The advice tree the experiment's advised runs train with."""
    advised = _advised_run(session, experiment)
    if advised.advice is None:
        raise InputError(f"experiment {experiment.id}'s runs have no advice tree")
    return tree_from_json(advised.advice)
