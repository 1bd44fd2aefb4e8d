"""The practice page before the bracket (issue 28 §3): one practice pair a page, a plain form
with two picture buttons, then the feedback and a link to the next pair or to the bracket
(:mod:`app.labelling.practice`).

The form is a GET: practice stores nothing, so the pair and the answer live in the URL
(``?pair=1&chose=left``) and a reload shows the same page; there is nothing for a CSRF
token to protect.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Request, Response

from app.core.json_types import IntParam
from app.http.deps import SessionDep, SettingsDep
from app.http.guards import PageParticipant
from app.http.rendering import PageRoute, RedirectTo, render
from app.labelling import practice
from app.labelling.pages import LABEL, PRACTICE, leave_if_ended
from app.labelling.practice_api import practice_image_url
from app.studies import service as studies
from engine.practice import MAX_PRACTICE_PAIRS, SIDES, PracticePair, Side

router = APIRouter(route_class=PageRoute, include_in_schema=False)


@router.get(PRACTICE)
def practice_page(
    request: Request,
    session: SessionDep,
    person: PageParticipant,
    settings: SettingsDep,
    pair: Annotated[int, IntParam(ge=0, le=MAX_PRACTICE_PAIRS - 1)] = 0,
    chose: Side | None = None,
) -> Response:
    """Practice pair ``pair``, or the feedback on choosing ``chose`` in it; the bracket once
    the participant has no practice (none asked, or a label given)."""
    leave_if_ended(session, person)
    found = practice.practice(session, participant=person, images_dir=settings.images_dir)
    if not found.pairs:
        raise RedirectTo(LABEL)
    shown = found.pair(pair)
    study = studies.get_study(session, study_id=person.study_id)
    return render(request, "practice.html", {"study": study, **_pair_context(shown, found, chose)})


def _pair_context(
    shown: PracticePair, found: practice.Practice, chose: Side | None
) -> dict[str, Any]:
    last = shown.position + 1 == len(found.pairs)
    return {
        "pair": shown,
        "total": len(found.pairs),
        "prompt": practice.PROMPTS[shown.kind],
        "pictures": {side: practice_image_url(shown.position, side) for side in SIDES},
        "chose": chose,
        "feedback": None if chose is None else practice.feedback(shown, chose),
        "last": last,
        "next_url": LABEL if last else f"{PRACTICE}?pair={shown.position + 1}",
    }
