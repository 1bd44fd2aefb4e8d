"""A study's open link ``/s/<slug>`` (issue 14; the pages are
:func:`app.recruiting.pages.open_link_router`'s, as for surveys), and the consistency check
after the bracket (clips where its pair has them, as on the bracket)."""

from __future__ import annotations

from fastapi import Request, Response

from app.core.errors import ConflictError
from app.core.json_types import form_int
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import SessionDep
from app.http.guards import PageParticipant
from app.http.rendering import RedirectTo, redirect, render
from app.labelling import check, dataset, participants, study_link
from app.labelling.open_matches import pair_shows_clips
from app.labelling.pages import THANKS, answer_refused, where_next
from app.recruiting import pages as recruiting_pages
from app.recruiting.seats import MemberEndedError
from app.studies import service as studies

CHECK = "/participate/check"
router = recruiting_pages.open_link_router(
    recruiting_pages.LinkPages(
        kind=study_link.LINK,
        name_of=lambda session, study_id: studies.get_ready_study(session, study_id=study_id).name,
        next_path=lambda session, person: where_next(
            participants.progress(session, participant=person)
        ),
        share_label=dataset.SHARE_LABEL,
    )
)


@router.get(CHECK)
def check_page(request: Request, session: SessionDep, person: PageParticipant) -> Response:
    """One first-round pair again, sides swapped (only when the study asks for it)."""
    pair = check.pending_pair(session, participant=person)
    if pair is None:
        raise RedirectTo(THANKS)
    study = studies.get_ready_study(session, study_id=person.study_id)
    clips = pair_shows_clips(session, study.id, pair.left, pair.right)
    return render(request, "crowd_check.html", {"study": study, "pair": pair, "clips": clips})


@router.post(CHECK, dependencies=[CsrfChecked])
def check_answer(
    request: Request, session: SessionDep, person: PageParticipant, fields: FormFields
) -> Response:
    """Store the check's answer (a plain form: two buttons) and what it showed
    (``stimulus``, stills for a form without it), then the thank-you page."""
    winner = form_int(fields.get("winner", ""))
    stimulus = fields.get("stimulus", "still")
    try:
        check.answer(
            session, participant=person, winner=-1 if winner is None else winner, stimulus=stimulus
        )
    except (ConflictError, MemberEndedError) as exc:
        return answer_refused(request, session, person, exc, link=THANKS)
    return redirect(THANKS)
