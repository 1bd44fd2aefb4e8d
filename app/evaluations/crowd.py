"""An evaluation's open link ``/e/<slug>`` (issue 41 §1: links like any study's): joining,
resuming, consent, seats, time limits and completion codes are :mod:`app.recruiting`'s, as
for studies and surveys; :data:`LINK` says what is an evaluation's own (its routes:
:mod:`app.evaluations.crowd_api`, :mod:`app.evaluations.crowd_pages`). A new evaluator gets
their pairs in the join's own transaction (:func:`app.evaluations.evaluators.stage`)."""

from __future__ import annotations

from app.evaluations import evaluators
from app.evaluations.service import get_ready_evaluation
from app.models import EvaluationLink
from app.recruiting.kinds import LinkKind
from app.recruiting.links import LinkFullError
from app.recruiting.members import EVALUATION


class EvaluationFullError(LinkFullError):
    """The evaluation's open link reached its largest number of evaluators."""


LINK = LinkKind(
    members=EVALUATION,
    link=EvaluationLink,
    # /e/ (evaluation), apart from /s/ and /q/: each kind of link has its own prefix.
    prefix="/e/",
    full_error=EvaluationFullError,
    check_collection=lambda session, evaluation_id: get_ready_evaluation(
        session, evaluation_id=evaluation_id
    ),
    stage=evaluators.stage,
    timed=True,
)
