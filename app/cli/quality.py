"""``acv gold add|list|remove``, ``acv study gate|quality`` and ``acv participant
exclude|include``: gold items, the qualification gate, label quality and exclusions from the
command line (issue 28 §1), through the same services as the REST API."""

from __future__ import annotations

import dataclasses
from typing import Annotated, Literal

import typer

from app.cli.options import id_option
from app.cli.root import cli
from app.cli.serve import cli_runtime
from app.cli.study import participant_cli, study_cli
from app.labelling import participants, quality, study_link
from app.recruiting import service as recruiting
from app.studies import crowd, gold

gold_cli = typer.Typer(help="Gold items: pairs with a right answer.", no_args_is_help=True)
cli.add_typer(gold_cli, name="gold")

StudyOpt = Annotated[int, id_option("Study id.")]
CandidateOpt = Annotated[int, typer.Option(min=0, help="A candidate id of the study.")]


@gold_cli.command("add")
def add(
    study: StudyOpt,
    a: CandidateOpt,
    b: CandidateOpt,
    answer: Annotated[int, typer.Option(min=0, help="The right answer: a or b.")],
    kind: Annotated[
        Literal["pair", "instructed"],
        typer.Option(help="pair: you answer it; instructed: the answer shows a marker."),
    ] = "pair",
) -> None:
    """Add a gold item; participants who join from now on get it. Prints its id."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        item = gold.add_item(session, study_id=study, kind=kind, a=a, b=b, answer=answer)
        typer.echo(
            f"gold item {item.id}: {item.kind} #{item.a} vs #{item.b}, answer #{item.answer}"
        )


@gold_cli.command("list")
def list_(study: StudyOpt) -> None:
    """One line per gold item: id, kind, pair, answer."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        for item in gold.list_items(session, study_id=study):
            typer.echo(f"{item.id}\t{item.kind}\t{item.a}\t{item.b}\t{item.answer}")


@gold_cli.command("remove")
def remove(study: StudyOpt, item: Annotated[int, id_option("Gold item id.")]) -> None:
    """Remove a gold item nobody answered."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        gold.delete_item(session, study_id=study, item_id=item)
    typer.echo(f"gold item {item} removed")


@study_cli.command("gate")
def gate(
    study: StudyOpt,
    gold_gate: Annotated[
        float | None,
        typer.Option(
            help="Flag a participant whose gold accuracy's 95% upper bound is below "
            "this (0 to 1); leave out for no gate."
        ),
    ] = None,
    excludes: Annotated[
        bool, typer.Option("--excludes/--flags-only", help="Also exclude whom the gate flags.")
    ] = False,
) -> None:
    """Set the study's qualification gate, keeping its open link and other options."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        row = recruiting.settings(session, study_link.LINK, study)
        kept = (
            crowd.CrowdOptions()
            if row is None
            else crowd.CrowdOptions(
                **{f.name: getattr(row, f.name) for f in dataclasses.fields(crowd.CrowdOptions)}
            )
        )
        options = dataclasses.replace(kept, gold_gate=gold_gate, gate_excludes=excludes)
        quality.configure_crowd(session, study_id=study, options=options)
        people = participants.list_participants(session, study_id=study)
        excluded = sum(s.participant.excluded for s in people)
    typer.echo(
        f"study {study}: gate {gold_gate if gold_gate is not None else 'off'}, "
        f"{'excludes' if excludes else 'flags only'}; {excluded} excluded"
    )


@study_cli.command("quality")
def quality_table(study: StudyOpt) -> None:
    """One line per participant: gold right/asked with its interval, ties, reliability,
    flags, and whether they are excluded."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        for q in quality.quality(session, study_id=study).participants:
            low, high = q.gold_interval or (float("nan"), float("nan"))
            person = q.participant
            state = f"excluded: {person.exclusion_reason}" if person.excluded else "included"
            typer.echo(
                f"{person.id}\tgold {q.gold.right}/{q.gold.asked} [{low:.2f}, {high:.2f}]"
                f"\tties {q.ties}\treliability {q.reliability:.2f}\t{','.join(q.flags) or '-'}"
                f"\t{state}"
            )


def _set_exclusion(participant: int, excluded: bool, reason: str | None) -> None:
    with cli_runtime() as runtime, runtime.sessions() as session:
        person = participants.set_exclusion(
            session, participant_id=participant, excluded=excluded, reason=reason
        )
        typer.echo(f"participant {person.id}: {person.exclusion_reason}")


@participant_cli.command("exclude")
def exclude(
    participant: Annotated[int, id_option("Participant id.")],
    reason: Annotated[str | None, typer.Option(help="Why (recorded).")] = None,
) -> None:
    """Leave a participant out of pooling and exports (their labels are kept)."""
    _set_exclusion(participant, True, reason)


@participant_cli.command("include")
def include(
    participant: Annotated[int, id_option("Participant id.")],
    reason: Annotated[str | None, typer.Option(help="Why (recorded).")] = None,
) -> None:
    """Take a participant back into pooling and exports."""
    _set_exclusion(participant, False, reason)
