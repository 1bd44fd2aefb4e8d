"""An evaluation's open link ``/e/<slug>`` (issue 41 §1: links like any study's): joining,
resuming, consent, seats, time limits and completion codes are :mod:`app.recruiting`'s, as
for studies and surveys; :data:`LINK` says what is an evaluation's own. A new evaluator gets
their pairs in the join's own transaction (:func:`app.evaluations.evaluators.stage`)."""

from __future__ import annotations

from app.evaluations import evaluators
from app.evaluations.service import get_evaluation, get_ready_evaluation
from app.models import EvaluationLink
from app.recruiting.api import LinkApi, open_link_api_router
from app.recruiting.kinds import LinkKind
from app.recruiting.links import LinkFullError
from app.recruiting.members import EVALUATION
from app.recruiting.pages import LinkPages, open_link_router
from app.recruiting.schemas import EvaluationCrowdOut, OpenLinkIn

#: Where an evaluator goes once they joined or came back.
EVALUATE = "/evaluate"


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

api_router = open_link_api_router(
    LinkApi(
        kind=LINK,
        collections="evaluations",
        tag="evaluations",
        name="evaluation_crowd",
        body=OpenLinkIn,
        out=EvaluationCrowdOut,
    )
)

pages_router = open_link_router(
    LinkPages(
        kind=LINK,
        name_of=lambda session, evaluation_id: (
            get_evaluation(session, evaluation_id=evaluation_id).name
        ),
        next_path=lambda session, person: EVALUATE,
    )
)
