"""The evaluator's practice page before their first pair (issue 41): one practice pair a
page, a plain GET form with two picture buttons, then the feedback and a link to the next
pair or to the evaluation (:mod:`app.evaluations.practice`; the study's practice page,
:mod:`app.labelling.practice_pages`, and its template). Practice stores nothing, so the pair
and the answer live in the URL (``?pair=1&chose=left``) and a reload shows the same page."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Request, Response

from app.core.json_types import IntParam
from app.evaluations import practice
from app.evaluations.pages import HEADER, PAIR, PRACTICE, PageEvaluator, context_of
from app.evaluations.practice_api import practice_image_url
from app.http.deps import SessionDep, SettingsDep
from app.http.rendering import PageRoute, RedirectTo, render
from app.labelling.practice import PROMPTS
from engine.practice import MAX_PRACTICE_PAIRS, SIDES, Side

router = APIRouter(route_class=PageRoute, include_in_schema=False)


@router.get(PRACTICE)
def practice_page(
    request: Request,
    session: SessionDep,
    person: PageEvaluator,
    settings: SettingsDep,
    pair: Annotated[int, IntParam(ge=0, le=MAX_PRACTICE_PAIRS - 1)] = 0,
    chose: Side | None = None,
) -> Response:
    """Practice pair ``pair``, or the feedback on choosing ``chose`` in it; the pairs once
    the evaluator has no practice (none asked, or an answer given)."""
    context_of(session, person)  # one who has ended goes to their last page
    found = practice.practice(session, evaluator=person, data_dir=settings.data_dir)
    if not found.pairs:
        raise RedirectTo(PAIR)
    shown = found.pair(pair)
    last = shown.position + 1 == len(found.pairs)
    context = {
        "header_name": HEADER,
        "pair": shown,
        "total": len(found.pairs),
        "prompt": PROMPTS[shown.kind],
        "pictures": {side: practice_image_url(shown.position, side) for side in SIDES},
        "chose": chose,
        "feedback": None if chose is None else practice.said(shown, chose),
        "last": last,
        "next_url": PAIR if last else f"{PRACTICE}?pair={shown.position + 1}",
        "practice_action": PRACTICE,
        "start_text": "Start the evaluation",
    }
    return render(request, "practice.html", context)
