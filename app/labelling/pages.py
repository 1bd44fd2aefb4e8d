"""Participant pages: the invite link, instructions, one match at a time, and thank you.

``/p/<token>`` stores the invite token in an HttpOnly cookie and sends the participant to
where they left off; the labelling page (``static/js/label.js``) then talks to the REST API
(``/api/participants/me/...``, ``/api/matches/{id}/label``) with that cookie.
"""

from __future__ import annotations

import contextlib
from typing import Any

from fastapi import APIRouter, Request, Response
from fastapi.responses import HTMLResponse, RedirectResponse
from sqlalchemy.orm import Session

from app.core.errors import AnsweredError, ConflictError
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import SessionDep, SettingsDep
from app.http.guards import PageParticipant, enter_by_invite
from app.http.rendering import PageRoute, RedirectTo, redirect, render, thumb_template
from app.labelling import check, dataset, disagreement, participants, practice, study_link
from app.models import Participant, utcnow
from app.recruiting import members, seats
from app.recruiting import service as recruiting
from app.studies import service as studies
from engine.errors import InputError

router = APIRouter(route_class=PageRoute, include_in_schema=False)

INSTRUCTIONS = "/participate"
PRACTICE = "/participate/practice"
LABEL = "/participate/label"
THANKS = "/participate/thanks"
PAIRS = "/participate/pairs"
SHARE = "/participate/share"
WITHDRAW = "/participate/withdraw"
ENDED = "/participate/ended"
#: What a participant who can do nothing more is told, by outcome.
ENDED_TEXT = {
    "withdrawn": (
        "You withdrew",
        "You withdrew from this study. Your answers are kept apart and will not be used.",
    ),
    "timed_out": (
        "Your time is over",
        "The time for this study ran out before you finished, so your place was given to "
        "someone else. Thank you for your time.",
    ),
    "failed_gate": (
        "This study has ended for you",
        "Some of your answers to the check pairs were not the expected ones, so the study "
        "stopped here. Thank you for your time.",
    ),
}


def where_next(progress: participants.Progress) -> str:
    """Where a participant continues: instructions, the next match, or the thank-you page."""
    if progress.finished:
        return THANKS
    return LABEL if progress.done else INSTRUCTIONS


@router.get("/p/{token}")
def invite_link(token: str, request: Request, session: SessionDep) -> RedirectResponse:
    """Remember the invitation in this browser and continue where the participant left off."""
    return enter_by_invite(
        request,
        session,
        members.STUDY,
        token,
        link_name="invite",
        next_path=lambda person: where_next(participants.progress(session, participant=person)),
    )


def leave_if_ended(session: Session, person: Participant) -> None:
    """Send a participant who has ended (withdrawn, out of time, stopped by the gate) to
    :data:`ENDED`: the first check of every page of the bracket and its practice."""
    if _outcome(session, person)[0].ended:
        raise RedirectTo(ENDED)


def _context(session: Session, person: Participant) -> dict[str, Any]:
    """What every page of the bracket shows (:func:`leave_if_ended` first)."""
    leave_if_ended(session, person)
    study = studies.get_study(session, study_id=person.study_id)
    return {
        "study": study,
        "participant": person,
        "thumb_template": thumb_template(study.id),
        "progress": participants.progress(session, participant=person),
    }


@router.get(INSTRUCTIONS)
def instructions(
    request: Request, session: SessionDep, person: PageParticipant, settings: SettingsDep
) -> HTMLResponse:
    """The study's instructions and a start (or continue) button: to the practice pairs
    when the participant has any (:mod:`app.labelling.practice`), else to the bracket."""
    pairs = practice.practice(session, participant=person, images_dir=settings.images_dir).pairs
    context = _context(session, person) | {
        "practice_pairs": len(pairs),
        "start_url": PRACTICE if pairs else LABEL,
        "share_label": dataset.SHARE_LABEL,
        "minutes_left": seats.minutes_left(person, utcnow()),
    }
    return render(request, "instructions.html", context)


@router.post(SHARE, dependencies=[CsrfChecked])
def share_choice(session: SessionDep, person: PageParticipant, fields: FormFields) -> Response:
    """Store the instructions page's sharing choice (ticked or not), then show the page; one
    who withdrew (another tab) goes to :data:`ENDED`."""
    share = fields.get("share") == "on"
    try:
        participants.set_share_consent(session, participant_id=person.id, share=share)
    except seats.MemberEndedError:
        return redirect(ENDED)
    return redirect(INSTRUCTIONS + "#share-form")


@router.get(LABEL)
def label_page(request: Request, session: SessionDep, person: PageParticipant) -> Response:
    """One match at a time (the page's script fetches and stores the matches)."""
    context = _context(session, person)
    if context["progress"].finished:
        raise RedirectTo(THANKS)
    return render(request, "label.html", context)


def _outcome(session: Session, person: Participant) -> tuple[seats.Outcome, seats.Ending | None]:
    failed_gate = person.gate_stopped_at is not None
    return recruiting.outcome(session, study_link.LINK, member=person, failed_gate=failed_gate)


@router.get(WITHDRAW)
def withdraw_page(request: Request, session: SessionDep, person: PageParticipant) -> Response:
    """Ask before withdrawing: what it means, and the way back."""
    context = _context(session, person)
    if context["progress"].finished:
        raise RedirectTo(THANKS)
    return render(request, "withdraw.html", context)


@router.post(WITHDRAW, dependencies=[CsrfChecked])
def withdraw(session: SessionDep, person: PageParticipant, fields: FormFields) -> Response:
    """Withdraw (their seat is freed, their labels left out of everything), then the page
    with the open link's code for it; only the form's own button withdraws."""
    if fields.get("decision") != "withdraw":
        raise InputError("withdrawing takes the form's Withdraw button (decision=withdraw)")
    with contextlib.suppress(seats.MemberEndedError):  # a second click: the ended page says so
        recruiting.withdraw(session, study_link.LINK, member=person)
    return redirect(ENDED)


@router.get(ENDED)
def ended(request: Request, session: SessionDep, person: PageParticipant) -> Response:
    """The last page of a participant who withdrew, ran out of time or was stopped by the
    gold gate: what happened, and their code and way back to the platform if any."""
    result, shown = _outcome(session, person)
    if not result.ended:
        raise RedirectTo(where_next(participants.progress(session, participant=person)))
    title, text = ENDED_TEXT[result.name]
    name = studies.get_study(session, study_id=person.study_id).name
    context = {"header_name": name, "title": title, "text": text, "ending": shown}
    return render(request, "member_message.html", context)


def answer_refused(
    request: Request,
    session: Session,
    person: Participant,
    exc: ConflictError | seats.MemberEndedError,
    *,
    link: str,
) -> Response:
    """The page for an answer after the bracket that is not stored: the ended page for one
    who withdrew or ran out of time, else (answered before with another choice, in a second
    tab or before going back; or nothing due) a page that says why, that what they answered
    before is kept, and that leads on to ``link``."""
    if isinstance(exc, seats.MemberEndedError):
        return redirect(ENDED)
    name = studies.get_study(session, study_id=person.study_id).name
    text = (
        "You answered this pair before with another choice; your first answer is kept."
        if isinstance(exc, AnsweredError)
        else f"This answer was not stored: {exc.detail}. What you answered before is kept."
    )
    context = {"header_name": name, "title": "Not stored", "text": text, "link": link}
    return render(request, "member_message.html", context, status_code=409)


@router.get(THANKS)
def thanks(request: Request, session: SessionDep, person: PageParticipant) -> Response:
    """Thank you, with the participant's Preference Tree (drawn by ``tree.js``)."""
    context = _context(session, person)
    if not context["progress"].finished:
        raise RedirectTo(LABEL)
    if disagreement.pending(session, participant=person) is not None:
        raise RedirectTo(PAIRS)
    if check.pending_pair(session, participant=person) is not None:
        raise RedirectTo("/participate/check")
    context["crowd"] = recruiting.completion(session, study_link.LINK, member=person)
    return render(request, "thanks.html", context)
