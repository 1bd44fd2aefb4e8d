"""An evaluation's open link ``/e/<slug>`` (issue 41 §1: links like any study's): joining,
resuming, consent, seats, time limits and completion codes are :mod:`app.recruiting`'s, as
for studies and surveys; :data:`LINK` says what is an evaluation's own (its routes:
:mod:`app.evaluations.crowd_api`, :mod:`app.evaluations.crowd_pages`). A new evaluator gets
their pairs in the join's own transaction (:func:`app.evaluations.evaluators.stage`)."""

from __future__ import annotations

from sqlalchemy.orm import Session

from app.evaluations import evaluators
from app.evaluations.service import get_ready_evaluation
from app.models import EvaluationLink, Evaluator
from app.recruiting.kinds import MemberKind
from app.recruiting.links import LinkFullError
from app.recruiting.members import EVALUATION


class EvaluationFullError(LinkFullError):
    """The evaluation's open link reached its largest number of evaluators."""


class EvaluationKind:
    """An evaluation's open link ``/e/<slug>`` (:class:`app.recruiting.kinds.MemberKind`):
    only an evaluation whose stills are rendered takes people, and a new evaluator gets their
    pairs as they join."""

    members = EVALUATION
    link = EvaluationLink
    # /e/ (evaluation), apart from /s/ and /q/: each kind of link has its own prefix.
    prefix = "/e/"
    full_error: type[LinkFullError] = EvaluationFullError
    timed = True

    def check_collection(self, session: Session, collection_id: int) -> None:
        """Refuse an evaluation that is not ready (:func:`get_ready_evaluation`)."""
        get_ready_evaluation(session, evaluation_id=collection_id)

    def stage(self, session: Session, member: Evaluator) -> None:
        """Add a new evaluator and their pairs (:func:`evaluators.stage`)."""
        evaluators.stage(session, member)


LINK: MemberKind[EvaluationLink, Evaluator] = EvaluationKind()
