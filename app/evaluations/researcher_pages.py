"""The researcher's agent evaluation pages (issue 41): an evaluation's status, design,
evaluators and answer; creating one from an experiment's page; inviting evaluators. The
evaluator's own pages are :mod:`app.evaluations.pages`."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Request, Response
from fastapi.responses import HTMLResponse
from pydantic import ValidationError
from sqlalchemy.orm import Session

from app.core.errors import ServiceError
from app.core.json_types import IntParam, from_form
from app.core.limits import MAX_BATCH, MAX_NAME_CHARS
from app.evaluations import crowd, evaluators, gold, results
from app.evaluations import service as evaluations
from app.evaluations.api import evaluator_out
from app.evaluations.link_pages import link_context, link_options
from app.evaluations.schemas import EvaluationDesign
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import DbId, RuntimeDep, SessionDep
from app.http.forms import REFUSED, invite_count, refused
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, redirect, render
from app.recruiting import service as recruiting
from app.recruiting.pages import form_echo
from engine.errors import InputError

router = APIRouter(route_class=PageRoute, include_in_schema=False)

#: The creation form's fields with their defaults, and what each is called on the page.
_PAIRS = str(evaluations.DEFAULT_PAIRS)
FORM = {
    "evaluator_kind": "others",
    "stimulus": "clip",
    "pairs_per_evaluator": _PAIRS,
    "show_bracket": "false",  # a checkbox: "on" when ticked, absent otherwise
    "gold_pairs": "0",
    "gold_gate": "",  # empty: no gate
    "practice_pairs": "0",
}
LABELS = {
    "evaluator_kind": "Who answers",
    "show_bracket": "Remind the advisor of their bracket",
    "stimulus": "What they see",
    "pairs_per_evaluator": "Pairs per evaluator",
    "gold_pairs": "Gold pairs per evaluator",
    "gold_gate": "Gold gate",
    "practice_pairs": "Practice pairs",
}


def experiment_section(session: Session, experiment_id: int) -> dict[str, Any]:
    """The experiment page's evaluations section: its evaluations and the creation form."""
    found = evaluations.list_evaluations(session, experiment_id=experiment_id)
    return {
        "evaluations": found,
        "evaluation_values": FORM,
        "evaluation_error": None,
        "evaluation_error_field": None,
    }


@router.post("/experiments/{experiment_id}/evaluations", dependencies=[ResearcherPage, CsrfChecked])
def create_evaluation(
    experiment_id: DbId,
    request: Request,
    session: SessionDep,
    runtime: RuntimeDep,
    fields: FormFields,
) -> Response:
    """Create an evaluation of the experiment's advised against its baseline runs, then its
    page; a bad design shows the form again with what is wrong."""
    advised, baseline = evaluations.experiment_arms(session, experiment_id=experiment_id)
    form = {name: fields.get(name, default) for name, default in FORM.items()}
    try:
        spec = _design(form).spec(advised, baseline, experiment_id=experiment_id)
        evaluation = evaluations.create_evaluation(session, spec=spec)
    except (InputError, ServiceError) as exc:  # a service error says its own status
        context = {"experiment_id": experiment_id, "evaluation_values": form}
        context["evaluation_error"] = getattr(exc, "detail", str(exc))
        context["evaluation_error_field"] = getattr(exc, "field", None)
        status = getattr(exc, "status_code", 422)
        return render(request, "evaluation_new.html", context, status_code=status)
    runtime.prepare_evaluation_later(evaluation.id)
    return redirect(f"/evaluations/{evaluation.id}")


def _design(form: dict[str, str]) -> EvaluationDesign:
    """The form's design, or :class:`InputError` saying which field is wrong and why."""
    try:
        fields = {name: value.strip() for name, value in form.items()}
        if not fields.get("gold_gate"):  # an empty gate: none
            fields.pop("gold_gate", None)
        return from_form(EvaluationDesign, fields)
    except ValidationError as exc:
        error = exc.errors()[0]
        field = str(error["loc"][0]) if error["loc"] else ""
        raise FieldError(field, f"{LABELS.get(field, 'The form')}: {error['msg']}") from None


class FieldError(InputError):
    """A form's field that is wrong (``field``, its name), and what is wrong with it."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


@router.get("/evaluations/{evaluation_id}", dependencies=[ResearcherPage])
def evaluation_page(
    evaluation_id: DbId,
    request: Request,
    session: SessionDep,
    invited: Annotated[int, IntParam(ge=0, le=MAX_BATCH)] = 0,
) -> HTMLResponse:
    """An evaluation: status, design, open link, evaluators and their links, the answer."""
    return _evaluation_page(request, session, evaluation_id, {"invited": invited})


@router.post("/evaluations/{evaluation_id}/crowd", dependencies=[ResearcherPage, CsrfChecked])
def set_crowd(
    evaluation_id: DbId, request: Request, session: SessionDep, fields: FormFields
) -> Response:
    """Save the open-link form, then the evaluation page's open-link section; a bad field
    shows the page again (422) with the form as it was sent and what is wrong.

    Raises:
        NotFoundError, ConflictError: no such evaluation, or it cannot take evaluators yet.
    """
    try:
        recruiting.configure(session, crowd.LINK, evaluation_id, link_options(fields))
    except InputError as exc:
        again = {"crowd_form": form_echo(fields), "crowd_error": str(exc)}
        return _evaluation_page(request, session, evaluation_id, again, status_code=422)
    return redirect(f"/evaluations/{evaluation_id}#crowd")


def _evaluation_page(
    request: Request,
    session: Session,
    evaluation_id: int,
    extra: dict[str, Any],
    status_code: int = 200,
) -> HTMLResponse:
    """The evaluation's page, with ``extra`` in its context."""
    evaluation = evaluations.get_evaluation(session, evaluation_id=evaluation_id)
    people = evaluators.list_evaluators(session, evaluation_id=evaluation_id)
    answer = results.result(session, evaluation_id=evaluation_id).to_json()
    slots = evaluations.slots(session, evaluation_id=evaluation_id)
    context = {
        "evaluation": evaluation,
        "evaluators": [evaluator_out(request, session, p) for p in people],
        "result": answer,
        "slots": list(zip(slots, answer["win_rates"], strict=True)),
        "tree_vs_asked": results.TREE_VS_ASKED,
        "gate_excluded": gold.gate_excluded(session, evaluation_id=evaluation_id),
        "invited": 0,
        "max_batch": MAX_BATCH,
        "max_name": MAX_NAME_CHARS,
    }
    context |= link_context(request, session, evaluation_id)  # the open link and its form
    return render(request, "evaluation.html", context | extra, status_code=status_code)


@router.post("/evaluations/{evaluation_id}/evaluators", dependencies=[ResearcherPage, CsrfChecked])
def invite(
    evaluation_id: DbId, request: Request, session: SessionDep, fields: FormFields
) -> Response:
    """Invite evaluators, then the evaluation's page with their links; a bad count shows the
    page again with the form as typed."""
    name = fields.get("name", "").strip()[:MAX_NAME_CHARS] or None
    try:
        count = invite_count(fields, "evaluators")
        people = evaluators.add_evaluators(
            session, evaluation_id=evaluation_id, count=count, name=name
        )
    except REFUSED as exc:
        again, status = refused("invite", fields, exc)
        return _evaluation_page(request, session, evaluation_id, again, status)
    return redirect(f"/evaluations/{evaluation_id}?invited={len(people)}#evaluators")
