"""``acv webhook add|list|remove|attempts|redeliver`` (issue 29 §3): a study's or a survey's
webhooks from the command line, through the same services as ``/api/webhooks``. Events are
delivered by the running server (``acv serve``), not by these commands."""

from __future__ import annotations

from typing import Annotated

import typer

from app.cli.options import id_option
from app.cli.root import cli, fail
from app.cli.serve import cli_runtime
from app.webhooks import service
from app.webhooks.outbox import Owner

webhook_cli = typer.Typer(
    help="Webhooks: signed POSTs of a study's or a survey's events.", no_args_is_help=True
)
cli.add_typer(webhook_cli, name="webhook")

StudyOpt = Annotated[int | None, id_option("Study id.")]
SurveyOpt = Annotated[int | None, id_option("Survey id.")]
WebhookOpt = Annotated[int, id_option("Webhook id.")]


def _owner(study: int | None, survey: int | None) -> Owner:
    if (study is None) == (survey is None):
        fail("give exactly one of --study and --survey")
    return Owner("study", study) if study is not None else Owner("survey", survey or 0)


@webhook_cli.command("add")
def add(
    url: Annotated[str, typer.Option(help="An https URL of a public address.")],
    study: StudyOpt = None,
    survey: SurveyOpt = None,
) -> None:
    """Register a URL; prints its id and the secret that signs its deliveries."""
    owner = _owner(study, survey)
    with cli_runtime() as runtime, runtime.sessions() as session:
        hook = service.register(
            session, owner=owner, url=url, targets=runtime.settings.webhook_targets
        )
    typer.echo(f"webhook {hook.id} for {owner.noun} {owner.id}: {hook.url}")
    typer.echo(f"secret: {hook.secret}")


@webhook_cli.command("list")
def list_(study: StudyOpt = None, survey: SurveyOpt = None) -> None:
    """One line per webhook: id, owner, URL, events delivered, pending and failed."""
    owner = None if study is None and survey is None else _owner(study, survey)
    with cli_runtime() as runtime, runtime.sessions() as session:
        hooks = service.list_webhooks(session, owner=owner)
        counts = service.counts(
            session,
            webhook_ids=[h.id for h in hooks],
            max_attempts=runtime.settings.webhook_max_attempts,
        )
    for h in hooks:
        own, c = service.owner_of(h), counts[h.id]
        typer.echo(
            f"{h.id}\t{own.noun} {own.id}\t{h.url}\t"
            f"{c.delivered} delivered, {c.pending} pending, {c.failed} failed"
        )


@webhook_cli.command("remove")
def remove(webhook: WebhookOpt) -> None:
    """Remove a webhook with its undelivered events: nothing more is sent to it."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        service.remove(session, webhook_id=webhook)
    typer.echo(f"webhook {webhook} removed")


@webhook_cli.command("attempts")
def attempts(
    webhook: WebhookOpt,
    limit: Annotated[int, typer.Option(min=1, max=service.MAX_LISTED)] = 50,
) -> None:
    """The latest delivery attempts, newest first: time, event, type, status, error, time taken."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        rows = service.attempts(session, webhook_id=webhook, limit=limit)
    for a in rows:
        status = f"HTTP {a.status_code}" if a.status_code is not None else "-"
        typer.echo(
            f"{a.attempted_at.isoformat()}\t{a.event_id}\t{a.type}\t{status}"
            f"\t{a.error or ''}\t{a.duration_ms} ms"
        )


@webhook_cli.command("redeliver")
def redeliver(
    webhook: WebhookOpt,
    event: Annotated[str, typer.Option(help="The event's id (its webhook-id header).")],
) -> None:
    """Send an event again, now, with a fresh series of attempts (the running server sends it)."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        service.redeliver(session, webhook_id=webhook, event_id=event)
    typer.echo(f"event {event} of webhook {webhook} queued for delivery")
