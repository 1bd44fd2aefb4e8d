"""Agent evaluation pages (issue 41): the evaluator's (invite link ``/v/<token>``, the
instructions, one pair a page as a plain form, thank you); the researcher's are
:mod:`app.evaluations.researcher_pages`.

Blind: an evaluator's page shows a pair's opaque key and its pictures' URLs under it, never
the evaluation's name (it may list run ids), a run id, slot, arm, seed or checkpoint. The HTML
shows stills; ``static/js/evaluate.js`` plays the clips with a Pause/Play toggle each (WCAG
2.2.2), or keeps the stills with a Play control under ``prefers-reduced-motion``.
"""

from __future__ import annotations

import re
import time
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Request, Response
from fastapi.responses import HTMLResponse, RedirectResponse
from sqlalchemy.orm import Session

from app.core.errors import ConflictError
from app.core.json_types import form_int
from app.evaluations import crowd, evaluators, practice, reminder
from app.evaluations import service as evaluations
from app.evaluations.evaluator_api import pair_out
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import SessionDep, SettingsDep
from app.http.guards import enter_by_invite, page_member
from app.http.member_auth import EvaluatorCookie
from app.http.rendering import PageRoute, RedirectTo, redirect, render
from app.models import Evaluator, utcnow
from app.recruiting import members, seats
from app.recruiting import service as recruiting
from engine.errors import InputError

router = APIRouter(route_class=PageRoute, include_in_schema=False)

INSTRUCTIONS = "/evaluate"
PAIR = "/evaluate/pair"
PRACTICE = "/evaluate/practice"
THANKS = "/evaluate/thanks"
SHARE = "/evaluate/share"
ENDED = "/evaluate/ended"
#: What an evaluator's pages are headed with (never the evaluation's name: it may name runs).
HEADER = "Agent evaluation"
ADVISOR_TEXT = (
    "Earlier you chose between pictures of this body in a bracket. Some of the agents you "
    "will see learned to move from your choices, others did not; you are not told which."
)
ENDED_TEXT = {
    "withdrawn": ("You withdrew", "You withdrew from this evaluation: it takes no more answers."),
    "timed_out": ("Your time is over", "The time for this evaluation ran out. Thank you!"),
    "ended": ("This evaluation has ended for you", "It takes no more answers. Thank you!"),
}
CHOICES: dict[str, evaluators.Choice] = {"left": "left", "right": "right", "tie": "tie"}
KEY = re.compile(r"[A-Za-z0-9_-]{1,32}")
MAX_RESPONSE_MS = 86_400_000


@router.get("/v/{token}")
def invite_link(token: str, request: Request, session: SessionDep) -> RedirectResponse:
    """Remember the evaluation's invitation in this browser, then the instructions."""
    return enter_by_invite(
        request,
        session,
        members.EVALUATION,
        token,
        link_name="evaluation",
        next_path=lambda person: INSTRUCTIONS,
    )


def page_evaluator(session: SessionDep, cookie: EvaluatorCookie = None) -> Evaluator:
    """The evaluator whose invite cookie this browser holds (:func:`page_member`)."""
    return page_member(
        session,
        members.EVALUATION,
        cookie,
        lost="This browser has no valid evaluation invitation. Open the link you were sent "
        "again (an invite link, /v/..., or the link on your study platform).",
    )


PageEvaluator = Annotated[Evaluator, Depends(page_evaluator)]


def _outcome(session: Session, person: Evaluator) -> tuple[seats.Outcome, seats.Ending | None]:
    """What became of the evaluator, and the open link's code and redirect for it."""
    return recruiting.outcome(session, crowd.LINK, member=person)


def context_of(session: Session, person: Evaluator) -> dict[str, Any]:
    """What every evaluator page shows; one who has ended goes to :data:`ENDED` instead."""
    if _outcome(session, person)[0].ended:
        raise RedirectTo(ENDED)
    evaluation = evaluations.get_evaluation(session, evaluation_id=person.evaluation_id)
    return {
        "header_name": HEADER,
        "kind": evaluation.evaluator_kind,
        "question": evaluation.question,
        "instructions": evaluation.instructions,
        "progress": evaluators.progress(session, evaluator_id=person.id),
        "evaluator": person,
    }


def _message(
    request: Request,
    title: str,
    text: str,
    link: str | None = None,
    ending: seats.Ending | None = None,
) -> HTMLResponse:
    """An evaluator's page with a message, a ``link`` on, and an open link's ``ending``."""
    context = {"header_name": HEADER, "title": title, "text": text, "link": link, "ending": ending}
    return render(request, "member_message.html", context)


@router.get(INSTRUCTIONS)
def instructions(
    request: Request, session: SessionDep, person: PageEvaluator, settings: SettingsDep
) -> Response:
    """What the evaluator is asked, and a Start (or Continue) button."""
    context = context_of(session, person)
    if context["progress"].finished:
        raise RedirectTo(THANKS)
    pairs = len(practice.practice(session, evaluator=person, data_dir=settings.data_dir).pairs)
    context |= {"advisor_text": ADVISOR_TEXT, "share_label": evaluators.SHARE_LABEL}
    context |= {"practice_pairs": pairs, "start_url": PRACTICE if pairs else PAIR}
    context["minutes_left"] = seats.minutes_left(person, utcnow())
    return render(request, "evaluate.html", context)


@router.post(SHARE, dependencies=[CsrfChecked])
def share_choice(session: SessionDep, person: PageEvaluator, fields: FormFields) -> Response:
    """Store the instructions page's sharing choice (ticked or not), then show the page; one
    who withdrew (another tab) goes to :data:`ENDED`."""
    try:
        evaluators.set_share_consent(session, person, share=fields.get("share") == "on")
    except seats.MemberEndedError:
        return redirect(ENDED)
    return redirect(INSTRUCTIONS + "#share-form")


@router.get(PAIR)
def pair_page(request: Request, session: SessionDep, person: PageEvaluator) -> Response:
    """The next pair still to answer, as a plain form; thank you once none is left."""
    context = context_of(session, person)
    pair = evaluators.next_pair(session, evaluator_id=person.id)
    if pair is None:
        raise RedirectTo(THANKS)
    shown = pair_out(session, person, pair)
    context |= {"pair": shown, "shown_at": int(time.time() * 1000), "reminder_text": reminder.TEXT}
    return render(request, "evaluate_pair.html", context)


@router.post(PAIR, dependencies=[CsrfChecked])
def pair_answer(
    request: Request, session: SessionDep, person: PageEvaluator, fields: FormFields
) -> Response:
    """Store the answer to the pair the form showed (what it showed: ``stimulus``), then
    the next pair."""
    key, choice = fields.get("key", ""), CHOICES.get(fields.get("choice", ""))
    stimulus = fields.get("stimulus", "still")
    if choice is None:
        raise InputError("choose the left agent, the right agent, or Can't tell")
    if stimulus not in ("still", "clip") or not KEY.fullmatch(key):
        raise InputError("this form is not one of this site's pair pages: reload the page")
    evaluation = evaluations.get_evaluation(session, evaluation_id=person.evaluation_id)
    shown = evaluators.Shown(stimulus=stimulus, reminder=reminder.shown(session, evaluation))
    took = _response_ms(fields)
    try:
        evaluators.answer(
            session, evaluator=person, key=key, choice=choice, response_ms=took, shown=shown
        )
    except seats.MemberEndedError:
        return redirect(ENDED)
    except ConflictError:
        text = "You answered this pair before, with another choice; the first answer is kept."
        response = _message(request, "Already answered", text, link=PAIR)
        response.status_code = 409
        return response
    return redirect(PAIR)


def _response_ms(fields: dict[str, str]) -> int | None:
    """The time to answer: measured by the page's script, else from when the page was made."""
    measured = form_int(fields.get("response_ms", ""))
    shown_at = form_int(fields.get("shown_at", ""))
    if measured is not None and measured >= 0:
        found = measured
    elif shown_at is not None and shown_at >= 0:
        found = int(time.time() * 1000) - shown_at
    else:
        return None
    return found if 0 <= found <= MAX_RESPONSE_MS else None


@router.get(THANKS)
def thanks(request: Request, session: SessionDep, person: PageEvaluator) -> Response:
    """Thank you, once every pair is answered."""
    progress = context_of(session, person)["progress"]
    if not progress.finished:
        raise RedirectTo(PAIR)
    text = f"You answered all {progress.total} pairs. You can close this page."
    ending = recruiting.completion(session, crowd.LINK, member=person)
    return _message(request, "Thank you!", text, ending=ending)


@router.get(ENDED)
def ended(request: Request, session: SessionDep, person: PageEvaluator) -> Response:
    """The last page of an evaluator who withdrew or ran out of time."""
    result, shown = _outcome(session, person)
    if not result.ended:  # back to where they are
        progress = evaluators.progress(session, evaluator_id=person.id)
        raise RedirectTo(THANKS if progress.finished else PAIR if progress.done else INSTRUCTIONS)
    return _message(request, *ENDED_TEXT.get(result.name, ENDED_TEXT["ended"]), ending=shown)
