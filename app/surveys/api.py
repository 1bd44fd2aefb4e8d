"""``/api/surveys``: tree-reading surveys (the researcher) and their screens (respondents).

Respondents send ``Authorization: Bearer <survey invite token>`` or carry the cookie that
their invite link ``/r/<token>`` sets (a cookie write must send ``X-Requested-With: acv``).
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response
from fastapi.responses import FileResponse

from app.core import auth
from app.core.errors import AuthError, NotFoundError
from app.core.rows import from_row
from app.http.deps import (
    AdminCredentials,
    CandidateId,
    DbId,
    ResearcherCookie,
    ResearcherDep,
    RuntimeDep,
    SessionDep,
    SettingsDep,
)
from app.http.files import attachment
from app.http.member_auth import RespondentCookie, RespondentCredentials, RespondentDep
from app.models import Survey, SurveyRespondent
from app.recruiting import members
from app.recruiting import service as recruiting
from app.studies import service as studies
from app.studies.images import MEDIA_TYPE, image_file
from app.surveys import answers as surveys_answers
from app.surveys import crowd, respond
from app.surveys import results as surveys_results
from app.surveys import service as surveys
from app.surveys.answers import AnswerIn
from app.surveys.schemas import (
    RespondentOut,
    RespondentsCreate,
    ScreenAnswers,
    SurveyCreate,
    SurveyOut,
)
from app.surveys.sources import source_menus

router = APIRouter(prefix="/surveys", tags=["surveys"])


def survey_out(survey: Survey, stimuli: list[dict[str, Any]] | None = None) -> SurveyOut:
    return from_row(
        SurveyOut, survey, exclusion_rule=surveys.exclusion_text(survey), stimuli=stimuli or []
    )


def respondent_out(request: Request, person: SurveyRespondent) -> RespondentOut:
    return from_row(
        RespondentOut,
        person,
        id=person.shown_id,
        invite_url=str(request.base_url).rstrip("/") + respond.invite_path(person.token),
        started=person.started_at is not None,
        finished=person.finished_at is not None,
        external_ids=person.external_ids or {},
    )


# --- respondents (before /{survey_id}, which would otherwise match "me") ---------------------


@router.get("/me")
def my_survey(session: SessionDep, person: RespondentDep) -> dict[str, Any]:
    """The respondent's survey: name, intro, and how many screens are answered; once an
    open-link respondent has finished, the completion code and redirect URL (or nulls)."""
    survey = surveys.get_survey(session, survey_id=person.survey_id)
    done, total = respond.progress(session, respondent_id=person.id)
    link = recruiting.completion(session, crowd.LINK, member=person)
    return {
        "survey_id": survey.id,
        "name": survey.name,
        "intro": survey.intro,
        "answered": done,
        "total": total,
        "finished": person.finished_at is not None,
        "completion_code": link.code if link else None,
        "redirect_url": link.redirect_url if link else None,
    }


@router.get("/me/screen", responses={204: {"description": "Every screen is answered."}})
def my_screen(session: SessionDep, person: RespondentDep) -> Any:
    """The next unanswered screen (two trees, left and right as planned, and the questions),
    or 204 when the survey is done."""
    found = respond.next_screen(session, respondent=person)
    if found is None:
        return Response(status_code=204)
    survey, screen, total = found
    return respond.screen_view(session, survey=survey, screen=screen, total=total)


@router.post(
    "/me/screens/{position}/answers",
    status_code=201,
    responses={200: {"description": "The same answers were stored before."}},
)
def answer_screen(
    position: DbId,
    body: ScreenAnswers,
    response: Response,
    session: SessionDep,
    person: RespondentDep,
) -> dict[str, Any]:
    """Store a screen's answers: 201 stored, 200 the same again, 409 answered differently."""
    answers = {k: AnswerIn(a.value, a.confidence) for k, a in body.answers.items()}
    if not surveys_answers.submit(
        session, respondent=person, position=position, answers=answers, screen_ms=body.screen_ms
    ):
        response.status_code = 200
    done, total = respond.progress(session, respondent_id=person.id)
    return {"position": position, "answered": done, "total": total}


# --- the researcher ----------------------------------------------------------------------


@router.get("/sources")
def tree_sources(session: SessionDep, _: ResearcherDep) -> dict[str, list[dict[str, Any]]]:
    """What a stimulus's trees can come from: finished participants, checkpoints whose agent
    trees are computed (with their judges), and ready studies (for uploads' images)."""
    return source_menus(session)


@router.post("", status_code=201)
def create_survey(body: SurveyCreate, session: SessionDep, _: ResearcherDep) -> SurveyOut:
    """Create and open a survey; its trees are frozen now (409 if a run's checkpoint has no
    computed agent trees yet)."""
    survey = surveys.create_survey(session, spec=body.spec())
    return survey_out(survey)


@router.get("")
def list_surveys(session: SessionDep, _: ResearcherDep) -> list[SurveyOut]:
    return [survey_out(s) for s in surveys.list_surveys(session)]


@router.get("/{survey_id}")
def get_survey(survey_id: DbId, session: SessionDep, _: ResearcherDep) -> SurveyOut:
    """The survey with its stimuli and their frozen trees."""
    survey = surveys.get_survey(session, survey_id=survey_id)
    stimuli = [
        {
            "id": s.id,
            "position": s.position,
            "label": s.label,
            "attention_check": s.attention_check,
            "expected": s.expected,
            "trees": s.trees,
        }
        for s in surveys.stimuli_of(session, survey_id=survey_id)
    ]
    return survey_out(survey, stimuli)


@router.post("/{survey_id}/respondents", status_code=201)
def add_respondents(
    survey_id: DbId,
    body: RespondentsCreate,
    request: Request,
    session: SessionDep,
    _: ResearcherDep,
) -> list[RespondentOut]:
    """Invite respondents; each gets an invite link ``/r/<token>``."""
    people = respond.add_respondents(session, survey_id=survey_id, count=body.count, name=body.name)
    return [respondent_out(request, p) for p in people]


@router.get("/{survey_id}/respondents")
def list_respondents(
    survey_id: DbId, request: Request, session: SessionDep, _: ResearcherDep
) -> list[RespondentOut]:
    return [
        respondent_out(request, p) for p in respond.list_respondents(session, survey_id=survey_id)
    ]


@router.get("/{survey_id}/results")
def survey_results_json(survey_id: DbId, session: SessionDep, _: ResearcherDep) -> dict[str, Any]:
    """Per stimulus and question: n, counts, accuracy with its Clopper-Pearson 95% CI and an
    exact binomial test against chance, mean confidence, median time; without and with the
    exclusions; and the paper's figures computed the same way."""
    return surveys_results.results(session, survey_id=survey_id)


@router.get(
    "/{survey_id}/answers.csv",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}},
)
def answers_csv(survey_id: DbId, session: SessionDep, _: ResearcherDep) -> Response:
    """One row per answer."""
    return attachment(
        surveys_results.export_csv(session, survey_id=survey_id),
        "text/csv; charset=utf-8",
        f"survey-{survey_id}-answers.csv",
    )


@router.get(
    "/{survey_id}/answers.jsonl",
    response_class=Response,
    responses={200: {"content": {"application/jsonl": {}}}},
)
def answers_jsonl(survey_id: DbId, session: SessionDep, _: ResearcherDep) -> Response:
    """One JSON object per line, per answer."""
    return attachment(
        surveys_results.export_jsonl(session, survey_id=survey_id),
        "application/jsonl",
        f"survey-{survey_id}-answers.jsonl",
    )


@router.get(
    "/{survey_id}/studies/{study_id}/candidates/{candidate_id}/thumb",
    response_class=FileResponse,
    responses={200: {"content": {MEDIA_TYPE: {}}}},
)
def thumbnail(
    survey_id: DbId,
    study_id: DbId,
    candidate_id: CandidateId,
    session: SessionDep,
    settings: SettingsDep,
    runtime: RuntimeDep,
    credentials: RespondentCredentials,
    _as_admin: AdminCredentials,
    cookie: RespondentCookie = None,
    researcher_cookie: ResearcherCookie = None,
) -> FileResponse:
    """A candidate's thumbnail, for the researcher and the survey's respondents, when one of
    the survey's trees is drawn over that study's candidates."""
    bearer = credentials.credentials if credentials is not None else None
    _check_viewer(session, runtime, survey_id, bearer, (researcher_cookie, cookie))
    if study_id not in _studies_of(session, survey_id):
        raise NotFoundError(f"survey {survey_id} shows no tree of study {study_id}")
    cand = studies.get_candidate(session, study_id=study_id, candidate_id=candidate_id)
    path = image_file(settings.data_dir, cand.thumb_path)
    if not path.is_file():
        raise NotFoundError(f"the image of candidate {candidate_id} is missing on disk")
    return FileResponse(
        path, media_type=MEDIA_TYPE, headers={"Cache-Control": "private, max-age=86400"}
    )


def _check_viewer(
    session: SessionDep,
    runtime: RuntimeDep,
    survey_id: int,
    bearer: str | None,
    cookies: tuple[str | None, str | None],
) -> None:
    """The researcher (by ``bearer`` or the first cookie), or a respondent of the survey
    (by ``bearer`` or the second cookie), or :class:`AuthError`."""
    researcher_cookie, respondent_cookie = cookies
    if auth.is_researcher(
        admin_token=runtime.admin_token,
        bearer=bearer,
        cookie=researcher_cookie,
        max_age_s=runtime.settings.session_max_age_s,
    ):
        return
    person = members.member_by_token(session, members.SURVEY, token=bearer or respondent_cookie)
    if person.survey_id != survey_id:
        raise AuthError("this invite is for another survey")


def _studies_of(session: SessionDep, survey_id: int) -> set[int]:
    return {
        t["study_id"]
        for s in surveys.stimuli_of(session, survey_id=survey_id)
        for t in s.trees
        if t["study_id"] is not None
    }
