"""Disagreement pairs after the bracket (issue 25 §5): one pair a page, a plain form with two
picture buttons, then the consistency check or the thank-you page
(:mod:`app.labelling.disagreement`). A pair with clips shows them as the bracket does
(``static/js/pair_motion.js``); the form posts what was shown (``stimulus``)."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from app.core.errors import ConflictError
from app.core.json_types import form_int
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import SessionDep
from app.http.guards import PageParticipant
from app.http.rendering import PageRoute, RedirectTo, redirect, render
from app.labelling import disagreement
from app.labelling.open_matches import pair_shows_clips
from app.labelling.pages import PAIRS, THANKS, answer_refused
from app.recruiting.seats import MemberEndedError
from app.studies import service as studies

router = APIRouter(route_class=PageRoute, include_in_schema=False)


@router.get(PAIRS)
def pair_page(request: Request, session: SessionDep, person: PageParticipant) -> Response:
    """The next pair still to answer; the thank-you page once none is left."""
    pair = disagreement.pending(session, participant=person)
    if pair is None:
        raise RedirectTo(THANKS)
    study = studies.get_ready_study(session, study_id=person.study_id)
    clips = pair_shows_clips(session, study.id, pair.left, pair.right)
    return render(request, "pair.html", {"study": study, "pair": pair, "clips": clips})


@router.post(PAIRS, dependencies=[CsrfChecked])
def pair_answer(
    request: Request, session: SessionDep, person: PageParticipant, fields: FormFields
) -> Response:
    """Store the answer to the pair the form showed (and what it showed: ``stimulus``, stills
    for a form without it), then the next one."""
    position, winner = (form_int(fields.get(name, "")) for name in ("position", "winner"))
    try:
        disagreement.answer(
            session,
            participant=person,
            position=-1 if position is None else position,  # -1: no such pair, a clear 4xx
            winner=-1 if winner is None else winner,
            stimulus=fields.get("stimulus", "still"),
        )
    except (ConflictError, MemberEndedError) as exc:
        return answer_refused(request, session, person, exc, link=PAIRS)
    return redirect(PAIRS)
