"""The Human and the Agent Preference Tree of a run, and their conformance ("anytime").

Everything here reads the checkpoint artefacts that the run's executor stored
(:mod:`app.runs.artefacts`): every judge's Agent Preference Tree, its conformance to the
run's advice tree (:class:`engine.conformance.Conformance`) and the per-candidate table. No
function here loads a checkpoint, imports torch or builds an env; a checkpoint whose artefact
is not stored yet raises :class:`app.core.errors.PendingError` (HTTP 202).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from sqlalchemy.orm import Session

from app.core import csv_export
from app.core.errors import ConflictError, PendingError
from app.models import CheckpointArtefact
from app.runs import artefacts, run_state
from engine.conformance import Conformance
from engine.errors import InputError
from engine.judges import DEFAULT_JUDGE, JUDGES, LEGACY_JUDGES, current_keys
from engine.records import CandidateRow
from engine.treefile import TreeDocument, tree_from_json

#: Columns of the conformance CSV exports (one row per checkpoint).
CSV_COLUMNS = (
    "checkpoint",
    "n_matches",
    "n_agree",
    "match_agreement",
    "match_agreement_ci_low",
    "match_agreement_ci_high",
    "kendall_tau_b",
    "tree_edit_distance",
    "same_champion",
    "n_rejected",
    "contested_n",
    "contested_kept",
    "reference_agreement",
)
#: The judges whose disagreement the verdict names: what the agent's reward says, what it does.
_REWARD_JUDGE, _BEHAVIOUR_JUDGE = "shaped", "behaviour"


#: The candidate column that holds a judge's score, where it is not the judge's own name.
_SCORE_COLUMN = {"shaped-value": "value", "return": "env_return"}


def score_column(judge: str) -> str:
    """The :class:`~engine.records.CandidateRow` field holding ``judge``'s score (``value``
    for ``shaped-value``, ``env_return`` for ``return``; else the judge's name)."""
    judge = LEGACY_JUDGES.get(judge, judge)
    return _SCORE_COLUMN.get(judge, judge)


@dataclass(frozen=True)
class CheckpointView:
    """One checkpoint as stored: every judge's tree and conformance, and the candidates."""

    step: int
    trees: dict[str, TreeDocument]
    conformance: dict[str, Conformance]
    candidates: list[CandidateRow]
    #: pooled advice: participant id -> judge -> that participant's tree judged by the agent
    advisors: dict[int, dict[str, Conformance]] = field(default_factory=dict)

    def tree(self, judge: str) -> TreeDocument:
        """The judge's Agent Preference Tree.

        Raises:
            InputError: the artefact has no tree for this judge.
        """
        judge = LEGACY_JUDGES.get(judge, judge)
        if judge not in self.trees:
            raise InputError(
                f"checkpoint {self.step} has no tree for judge {judge!r}; it has: "
                f"{', '.join(sorted(self.trees)) or 'none'}"
            )
        return self.trees[judge]

    def of(self, judge: str) -> Conformance:
        """The judge's conformance to the advice tree."""
        self.tree(judge)
        return self.conformance[LEGACY_JUDGES.get(judge, judge)]

    def advisors_of(self, judge: str) -> list[tuple[int, Conformance]]:
        """Pooled advice: (participant id, the judge's conformance to their tree), by id;
        empty for other runs."""
        self.tree(judge)
        judge = LEGACY_JUDGES.get(judge, judge)
        return [(pid, by[judge]) for pid, by in sorted(self.advisors.items())]


def pick_checkpoint(session: Session, *, run_id: int, step: int | None) -> int:
    """``step`` if the run has it, else (for None) its latest checkpoint.

    Raises:
        ConflictError: no checkpoint yet (a state the run will leave, not bad input).
        InputError: no checkpoint at ``step``.
    """
    steps = run_state.checkpoint_steps(session, run_id=run_id)
    if not steps:
        raise ConflictError("the run has no checkpoint yet")
    if step is None:
        return steps[-1]
    if step not in steps:
        raise InputError(
            f"the run has no checkpoint at step {step}; it has {', '.join(map(str, steps))}"
        )
    return step


def shown_judge(session: Session, *, run_id: int, step: int | None) -> str:
    """The judge a page shows when none is asked for: the default one, unless the checkpoint
    was judged before it existed (then the first of :data:`JUDGES` that it has)."""
    row = None if step is None else session.get(CheckpointArtefact, (run_id, step))
    if row is None or not artefacts.judged(row.payload):
        return DEFAULT_JUDGE
    stored = current_keys(row.payload.get("judges") or {})
    return next((j for j in (DEFAULT_JUDGE, *JUDGES) if j in stored), DEFAULT_JUDGE)


def view_of(step: int, body: dict[str, Any]) -> CheckpointView:
    """A stored ``acv.checkpoint/1`` document as a :class:`CheckpointView`."""
    judges = current_keys(body.get("judges") or {})
    return CheckpointView(
        step=step,
        trees={j: tree_from_json(v["tree"]) for j, v in judges.items()},
        conformance={j: Conformance.from_json(v["conformance"]) for j, v in judges.items()},
        candidates=[CandidateRow(**row) for row in body.get("candidates") or []],
        advisors={
            int(a["participant_id"]): {
                j: Conformance.from_json(c) for j, c in current_keys(a["judges"]).items()
            }
            for a in body.get(artefacts.ADVISORS) or []
        },
    )


def checkpoint_view(session: Session, *, run_id: int, step: int) -> CheckpointView:
    """The stored artefact of one checkpoint.

    Raises:
        PendingError: not computed yet.
    """
    return view_of(step, artefacts.payload(session, run_id=run_id, step=step))


def conformance_curve(
    session: Session, *, run_id: int, judge: str
) -> list[tuple[int, Conformance]]:
    """(step, conformance) at every judged checkpoint, increasing steps.

    Raises:
        PendingError: the run has checkpoints, but none is judged yet.
    """
    stored = artefacts.payloads(session, run_id=run_id)
    if not stored and run_state.checkpoint_steps(session, run_id=run_id):
        raise PendingError(f"the conformance curve of run {run_id} is being computed")
    return [
        (step, view_of(step, body).of(judge))
        for step, body in stored.items()
        if artefacts.judged(body)  # a corrupt checkpoint has no point on the curve
    ]


def _kept(c: Conformance) -> bool:
    """Whether a judge keeps the advice where it matters: its contested matches if any."""
    if c.contested.n:
        return 2 * c.contested.kept > c.contested.n
    return 2 * c.n_agree > c.n_matches


def verdict(view: CheckpointView, judge: str, whose: str = "your") -> str:
    """Plain sentences, contested matches first, e.g. ``Of the 5 choices where your advice
    goes against the environment's reward, the agent kept 3. ...``."""
    m = view.of(judge)
    if m.contested.n:
        text = (
            f"Of the {m.contested.n} choices where {whose} advice goes against the "
            f"environment's reward, the agent kept {m.contested.kept}."
        )
    else:
        text = (
            f"None of {whose} choices goes against the environment's reward, so this "
            f"bracket cannot tell whether the agent used {whose} advice."
        )
    rejected = m.n_matches - m.n_agree
    text += f" Overall it kept {m.n_agree} of {m.n_matches} of {whose} choices"
    text += (
        " and rejected none."
        if rejected == 0
        else f" and overturned {rejected} ({rejected / m.n_matches:.0%})."
    )
    text += " It agrees on the champion." if m.same_champion else " It crowns a different champion."
    return f"{text}{_disagreement(view, whose)}"


def _disagreement(view: CheckpointView, whose: str) -> str:
    if _REWARD_JUDGE not in view.conformance or _BEHAVIOUR_JUDGE not in view.conformance:
        return ""
    reward, behaviour = (_kept(view.conformance[j]) for j in (_REWARD_JUDGE, _BEHAVIOUR_JUDGE))
    if reward and not behaviour:
        return (
            f" The judges disagree: its reward follows {whose} advice, but its behaviour does not."
        )
    if behaviour and not reward:
        return (
            f" The judges disagree: its behaviour follows {whose} advice, but its reward does not."
        )
    return ""


def highlights(m: Conformance) -> tuple[frozenset[int], frozenset[int]]:
    """States to mark: the human's loser of each overturned match in the human tree, and the
    human's winner (which the agent ruled against) in the agent's tree."""
    human = frozenset(r.b if r.human_winner == r.a else r.a for r in m.rejected)
    return human, frozenset(r.human_winner for r in m.rejected)


def csv_text(rows: list[tuple[int, Conformance]]) -> str:
    """Conformance metrics (one per checkpoint) as CSV with :data:`CSV_COLUMNS`."""
    return csv_export.csv_text(CSV_COLUMNS, (_csv_row(step, m) for step, m in rows))


def _csv_row(step: int, m: Conformance) -> tuple[object, ...]:
    low, high = m.match_agreement_ci
    return (
        step,
        m.n_matches,
        m.n_agree,
        m.match_agreement,
        low,
        high,
        m.kendall_tau_b,
        m.tree_edit_distance,
        m.same_champion,
        len(m.rejected),
        m.contested.n,
        m.contested.kept,
        m.reference_agreement,
    )
