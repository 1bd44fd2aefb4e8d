"""Practice before an evaluation's first pair (issue 41): a study's practice, for evaluators.

An evaluation with ``practice_pairs = k`` (2 to 5) shows each evaluator ``k`` practice pairs
after the instructions and before their first pair, exactly as a study shows its
participants (:mod:`app.labelling.practice`, :func:`engine.practice.practice_plan`): about
half instructed ("choose the picture with the marker", right or wrong), the others with no
right answer; seeded by the evaluation's seed and the evaluator's id, so a reload shows the
same pair; nothing stored; none once the evaluator has an answer.

Practice must not prime: its pictures are never the evaluation's agents. They are practice
states of the env (random rollouts, :func:`engine.practice.sample_practice_states`), sampled,
rendered and stored when the evaluation is prepared, by the studies' own code
(:mod:`app.studies.practice_states`) in a folder of evaluations' own.
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy.orm import Session

from app.evaluations.evaluators import progress
from app.evaluations.service import get_evaluation
from app.labelling.practice import Feedback, Practice, feedback
from app.models import Evaluation, Evaluator
from app.studies.practice_states import practice_states, prepare_practice
from engine.practice import PracticePair, practice_plan
from engine.render import RenderService

#: What a pair with no right answer says, in an evaluation's words.
NO_RIGHT_ANSWER = (
    "There is no right answer here. In the real pairs there is none either: choose the agent "
    "that better does what you are asked."
)


def practice_dir(data_dir: Path) -> Path:
    """Where evaluations' practice states are stored (``practice/<evaluation id>/`` under)."""
    return data_dir / "evaluation_practice"


def prepare(renderer: RenderService, *, data_dir: Path, evaluation: Evaluation) -> None:
    """Sample, render and store the evaluation's practice states (nothing when it asks
    none); none equals a candidate of any study, as they come from practice's own stream."""
    prepare_practice(renderer, images_dir=practice_dir(data_dir), study=evaluation, exclude=())


def practice(session: Session, *, evaluator: Evaluator, data_dir: Path) -> Practice:
    """The evaluator's practice; no pairs when the evaluation asks none, once they have an
    answer, or when its practice states are missing on disk (logged)."""
    evaluation = get_evaluation(session, evaluation_id=evaluator.evaluation_id)
    if evaluation.practice_pairs == 0 or progress(session, evaluator_id=evaluator.id).done:
        return Practice([], None)
    states = practice_states(practice_dir(data_dir), evaluation)
    if states is None:
        return Practice([], None)
    plan = practice_plan(
        evaluation.practice_pairs, seed=evaluation.seed, participant_id=evaluator.id
    )
    return Practice(plan, states)


def said(pair: PracticePair, side: str) -> Feedback:
    """The feedback on choosing ``side`` of ``pair`` (:func:`app.labelling.practice.feedback`,
    in an evaluation's words where there is no right answer)."""
    found = feedback(pair, side)
    return found if found.correct is not None else Feedback(None, None, NO_RIGHT_ANSWER)
