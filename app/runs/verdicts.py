"""An experiment's verdict: its advised runs against their matched baseline at one
checkpoint step, for one judge.

It reads the runs' stored checkpoint artefacts (the per-candidate table that each run's
executor writes) and hands them to :func:`engine.verdict_outcome.verdict`. By default the
step is the latest one judged in enough runs of every role (:data:`MIN_JUDGED`), so the
verdict can be looked at while runs train; only a final one, by a verdict judge, decides
(:attr:`ExperimentVerdict.decides`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.labelling import disagreement
from app.models import CheckpointArtefact, Experiment, ExperimentRole, Run, RunCheckpoint
from app.runs import artefacts
from app.runs.experiments import get_experiment, members
from app.runs.imported import is_external, latest_only
from engine.errors import InputError
from engine.judges import JUDGE_COLUMNS, VERDICT_JUDGES, judge_name
from engine.treefile import TreeDocument, tree_from_json
from engine.verdict import Pair, Verdict, VerdictInputs, advice_scores, bracket_pairs
from engine.verdict_outcome import verdict

#: role -> run id -> step -> the per-candidate rows of that judged checkpoint.
JudgedTables = dict[ExperimentRole, dict[int, dict[int, list[dict[str, Any]]]]]
#: Fewest runs per role with a judged checkpoint before a verdict is attempted.
MIN_JUDGED = {ExperimentRole.ADVISED: 2, ExperimentRole.BASELINE: 2, ExperimentRole.PILOT: 1}


@dataclass(frozen=True)
class ExperimentVerdict:
    """The verdict of one judge at one checkpoint step, and the runs it rests on. ``final``:
    it rests on every run of the experiment, each at its last checkpoint. Only a final
    verdict of a verdict judge :attr:`decides` (gets an outcome word on the pages); the rest
    are interim or diagnostic looks, which must not each be able to say "used"."""

    judge: str
    step: int
    verdict: Verdict
    runs: dict[ExperimentRole, list[int]] = field(default_factory=dict)
    final: bool = False

    @property
    def diagnostic(self) -> bool:
        """Its judge is one that never leads a verdict (:data:`VERDICT_JUDGES`)."""
        return judge_name(self.judge) not in VERDICT_JUDGES

    @property
    def decides(self) -> bool:
        """Final, and by a verdict judge."""
        return self.final and not self.diagnostic


def experiment_verdict(
    session: Session, *, experiment_id: int, judge: str, step: int | None = None
) -> ExperimentVerdict | None:
    """The verdict of ``judge`` at ``step`` (default: the latest step judged in enough runs
    of every role, :data:`MIN_JUDGED`; for an external experiment, each run's own checkpoint,
    reported as the largest of their steps); None while no such step exists yet.

    Raises:
        NotFoundError: no such experiment, or ``step`` is no checkpoint of its runs.
        InputError: not a judge, or one the runs' artefacts do not score (an external
            experiment's: any but the verdict judges).
    """
    experiment = get_experiment(session, experiment_id=experiment_id)
    external = is_external(experiment)
    if judge_name(judge) not in VERDICT_JUDGES and external:  # an unknown judge: InputError
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
    final = _is_final([run for _, run in runs_], used, step, external=external)
    return ExperimentVerdict(judge=judge, step=step, verdict=result, runs=used, final=final)


def _is_final(
    every: list[Run], used: dict[ExperimentRole, list[int]], step: int, *, external: bool
) -> bool:
    """Whether the verdict rests on every run of the experiment at its last checkpoint: a
    run saves that one on reaching its planned timesteps (earlier ones fall short of them);
    an imported policy is judged at its one checkpoint."""
    if sum(map(len, used.values())) < len(every):
        return False
    return external or all(step >= run.timesteps for run in every)


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
