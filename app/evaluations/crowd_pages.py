"""An evaluation's open link ``/e/<slug>``: the open-link pages of
:func:`app.recruiting.pages.open_link_router`, as for studies and surveys. The header names
no evaluation (its name may list its runs: the evaluation is blind)."""

from __future__ import annotations

from app.evaluations.crowd import LINK
from app.evaluations.evaluators import SHARE_LABEL
from app.evaluations.pages import HEADER, INSTRUCTIONS
from app.recruiting.pages import LinkPages, open_link_router

router = open_link_router(
    LinkPages(
        kind=LINK,
        name_of=lambda session, evaluation_id: HEADER,
        next_path=lambda session, person: INSTRUCTIONS,
        share_label=SHARE_LABEL,
    )
)
