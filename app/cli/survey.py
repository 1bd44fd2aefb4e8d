"""``acv survey create|add-respondents|results|export``: tree-reading surveys from the command
line, through the same service layer and the same validation as ``POST /api/surveys``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Literal

import typer
from pydantic import ValidationError

from app.cli.options import id_option
from app.cli.root import cli, fail, validation_errors
from app.cli.serve import cli_runtime
from app.surveys import respond
from app.surveys import results as surveys_results
from app.surveys import service as surveys
from app.surveys.schemas import SurveyCreate

survey_cli = typer.Typer(
    help="Tree-reading surveys (the paper's user study).", no_args_is_help=True
)
cli.add_typer(survey_cli, name="survey")


def _spec(path: Path) -> SurveyCreate:
    """The survey file, validated as the API validates its body (one line on failure)."""
    try:
        return SurveyCreate.model_validate_json(path.read_bytes())
    except ValidationError as exc:
        fail(f"{path}: {validation_errors(exc, 'the file')}")


@survey_cli.command("create")
def create(
    spec: Annotated[
        Path,
        typer.Option(
            help="JSON file with the body of POST /api/surveys (trees: participant, run or "
            "upload with an inline acv.tree/1 doc)."
        ),
    ],
) -> None:
    """Create and open a survey; prints its id."""
    body = _spec(spec)
    with cli_runtime() as runtime, runtime.sessions() as session:
        survey = surveys.create_survey(session, spec=body.spec())
        n = len(surveys.stimuli_of(session, survey_id=survey.id))
    typer.echo(
        f"survey {survey.id} open: {n} stimuli, exclusion rule: {surveys.exclusion_text(survey)}"
    )


@survey_cli.command("add-respondents")
def add_respondents(
    survey: Annotated[int, id_option("Survey id.")],
    count: Annotated[int, typer.Option(help="How many invite links (1..500).")] = 1,
    base_url: Annotated[str, typer.Option(help="Base of the printed links.")] = "",
) -> None:
    """Invite respondents; prints one invite link per line."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        base = (base_url or runtime.settings.public_url or "http://127.0.0.1:8000").rstrip("/")
        people = respond.add_respondents(session, survey_id=survey, count=count)
    for person in people:
        typer.echo(f"{person.id}\t{base}{respond.invite_path(person.token)}")


@survey_cli.command("results")
def results(
    survey: Annotated[int, id_option("Survey id.")],
    as_json: Annotated[
        bool, typer.Option("--json", help="The results JSON of GET /api/surveys/{id}/results.")
    ] = False,
) -> None:
    """Per stimulus and question: n, accuracy with its 95% CI and p vs chance."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        out = surveys_results.results(session, survey_id=survey)
    if as_json:
        typer.echo(json.dumps(out, indent=1))
        return
    typer.echo(f"survey {out['survey_id']}: {out['name']} ({out['exclusion_rule']})")
    for key, title in (
        ("without_exclusions", "without exclusions"),
        ("with_exclusions", "with exclusions"),
    ):
        typer.echo(f"-- {title}")
        for block in out[key]:
            typer.echo(_line(block))
    for fig in out["paper"]:
        typer.echo(
            f"paper {fig['question']}: {fig['k']}/{fig['n']}, 95% CI "
            f"[{fig['ci_low']:.3f}, {fig['ci_high']:.3f}], p = {fig['p_value']:.2g}"
        )


def _line(block: dict) -> str:
    head = f"{block['stimulus']} {block['question']}: n = {block['n']}"
    acc = block["accuracy"]
    if acc is None:
        return f"{head}, {block['counts']}"
    return (
        f"{head}, {acc['k']}/{acc['n']} as expected, 95% CI [{acc['ci_low']:.3f}, "
        f"{acc['ci_high']:.3f}], p = {acc['p_value']:.2g} vs chance {acc['chance']:.2f}"
    )


@survey_cli.command("export")
def export(
    survey: Annotated[int, id_option("Survey id.")],
    out: Annotated[Path, typer.Option(help="File to write.")],
    fmt: Annotated[Literal["csv", "jsonl"], typer.Option("--format")] = "csv",
) -> None:
    """One row per answer, as CSV or JSONL."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        write = surveys_results.export_csv if fmt == "csv" else surveys_results.export_jsonl
        out.write_text(write(session, survey_id=survey), encoding="utf-8")
    typer.echo(f"wrote {out}")
