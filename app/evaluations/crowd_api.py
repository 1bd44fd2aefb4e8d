"""``/api/evaluations/{id}/crowd``: an evaluation's open link ``/e/<slug>`` and its options,
with the counts of evaluators who joined and declined consent. Researcher only."""

from __future__ import annotations

from app.evaluations.crowd import LINK
from app.recruiting.api import LinkApi, open_link_api_router
from app.recruiting.schemas import EvaluationCrowdOut, OpenLinkIn

router = open_link_api_router(
    LinkApi(
        kind=LINK,
        collections="evaluations",
        tag="evaluations",
        name="evaluation_crowd",
        body=OpenLinkIn,
        out=EvaluationCrowdOut,
    )
)
