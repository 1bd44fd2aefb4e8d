"""An experiment's verdict where a researcher reads a run: its comparison pages, its HTML
report, and a CSV of the per-seed numbers the verdict rests on.

The verdict itself is :func:`app.runs.verdicts.experiment_verdict`; this module only
says which judge a run's page asks it for, and lays the result out.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from sqlalchemy.orm import Session

from app.models import ExperimentRole
from app.runs.experiments import experiments_of_run, members
from app.runs.verdicts import ExperimentVerdict, experiment_verdict
from engine.errors import InputError
from engine.judges import DEFAULT_JUDGE, VERDICT_JUDGES

#: Columns of ``/api/experiments/{id}/verdict.csv``: one row per run the verdict rests on.
CSV_HEADER: tuple[str, ...] = (
    "experiment_id",
    "judge",
    "step",
    "role",
    "run_id",
    "seed",
    "ca",
    "contested_matches",
    "delta",
    "ci_low",
    "ci_high",
    "p_value",
    "auc",
    "outcome",
)


@dataclass(frozen=True)
class ExperimentNote:
    """One experiment of a run, as its pages show it.

    Attributes:
        experiment_id: the experiment.
        found: its verdict; None while pending or where ``problem`` says why not.
        problem: why no verdict can be given with this judge (checkpoints judged before it
            existed), else None.
    """

    experiment_id: int
    found: ExperimentVerdict | None
    problem: str | None = None


def verdict_judge(judge: str) -> str:
    """The judge a run's page asks the verdict for: its own, if that one leads verdicts."""
    return judge if judge in VERDICT_JUDGES else DEFAULT_JUDGE


def notes_of_runs(session: Session, *, run_ids: Iterable[int], judge: str) -> list[ExperimentNote]:
    """The verdict of every experiment that any of ``run_ids`` belongs to, by
    :func:`verdict_judge`, in experiment order."""
    ids = sorted({e for run_id in run_ids for e in experiments_of_run(session, run_id=run_id)})
    return [_note(session, experiment_id, verdict_judge(judge)) for experiment_id in ids]


def _note(session: Session, experiment_id: int, judge: str) -> ExperimentNote:
    try:
        found = experiment_verdict(session, experiment_id=experiment_id, judge=judge)
    except InputError as exc:
        return ExperimentNote(experiment_id, None, str(exc))
    return ExperimentNote(experiment_id, found)


def verdict_rows(
    session: Session, *, experiment_id: int, found: ExperimentVerdict
) -> list[dict[str, Any]]:
    """:data:`CSV_HEADER` rows: per advised and baseline run its CA (share of the contested
    matches kept), per pilot run none (pilots pick the matches); the verdict on every row."""
    v = found.verdict
    seeds = {run.id: run.seed for _, run in members(session, experiment_id=experiment_id)}
    low, high = v.interval if v.interval is not None else (None, None)
    shared = {
        "experiment_id": experiment_id,
        "judge": found.judge,
        "step": found.step,
        "contested_matches": len(v.matches.contested),
        "delta": v.delta,
        "ci_low": low,
        "ci_high": high,
        "p_value": v.p_value,
        "auc": v.auc,
        "outcome": v.outcome,
    }
    ca = {ExperimentRole.ADVISED: v.ca_advised, ExperimentRole.BASELINE: v.ca_baseline}
    return [
        shared | {"role": role, "run_id": run_id, "seed": seeds[run_id], "ca": _at(ca, role, i)}
        for role in ExperimentRole
        for i, run_id in enumerate(found.runs.get(role, []))
    ]


def _at(ca: dict[ExperimentRole, tuple[float, ...]], role: ExperimentRole, i: int) -> float | None:
    values = ca.get(role, ())
    return values[i] if i < len(values) else None
