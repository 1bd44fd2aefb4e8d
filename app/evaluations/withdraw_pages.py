"""An evaluator's withdraw page ``/evaluate/withdraw`` (issue 41 §1: links like any
study's), as a study participant's ``/participate/withdraw``: a page that asks first, and a
plain form whose own button withdraws.

Withdrawing frees the evaluator's seat on the open link and leaves their answers out of the
answer and the exports (they are kept, never deleted); the ended page then shows the open
link's decline code and the way back to the platform, if the researcher set them.
"""

from __future__ import annotations

import contextlib

from fastapi import APIRouter, Request, Response

from app.evaluations import crowd
from app.evaluations.pages import ENDED, PAIR, THANKS, PageEvaluator, context_of
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import SessionDep
from app.http.rendering import PageRoute, RedirectTo, redirect, render
from app.recruiting import seats
from app.recruiting import service as recruiting
from engine.errors import InputError

router = APIRouter(route_class=PageRoute, include_in_schema=False)

WITHDRAW = "/evaluate/withdraw"


@router.get(WITHDRAW)
def withdraw_page(request: Request, session: SessionDep, person: PageEvaluator) -> Response:
    """Ask before withdrawing: what it means, and the way back to the pairs."""
    context = context_of(session, person)
    if context["progress"].finished:
        raise RedirectTo(THANKS)
    return render(request, "evaluate_withdraw.html", context | {"back": PAIR})


@router.post(WITHDRAW, dependencies=[CsrfChecked])
def withdraw(session: SessionDep, person: PageEvaluator, fields: FormFields) -> Response:
    """Withdraw (the seat is freed, the answers left out of everything), then the ended page
    with the open link's code for it; only the form's own button withdraws.

    Raises:
        InputError: the post is not the form's Withdraw button (422).
    """
    if fields.get("decision") != "withdraw":
        raise InputError("withdrawing takes the form's Withdraw button (decision=withdraw)")
    with contextlib.suppress(seats.MemberEndedError):  # a second click: the ended page says so
        recruiting.withdraw(session, crowd.LINK, member=person)
    return redirect(ENDED)
