"""``acv webhook add|list|remove|attempts|redeliver`` (issue 29 §3), on SQLite and
PostgreSQL: the same services as ``/api/webhooks``; bad input (not https, a private or public
address, no owner) is one line on stderr and exit code 2, and changes nothing."""

from __future__ import annotations

import re

import pytest
from sqlalchemy import create_engine, select, update

from app.models import WebhookEvent
from tests.support.cli import acv


@pytest.fixture
def run(monkeypatch, backend_url):
    """Invoke ``acv`` in-process on this module's database; webhooks to 127.0.0.1 only."""
    data_dir, url = backend_url
    monkeypatch.setenv("ACV_DATA_DIR", str(data_dir))
    monkeypatch.setenv("DATABASE_URL", url)
    monkeypatch.setenv("ACV_WEBHOOK_TARGETS", "loopback")
    return acv


@pytest.fixture
def study_id(run) -> str:
    made = run("study", "create", "--name", "w", "--env", "Hopper-v5", "--candidates", "4")
    assert made.exit_code == 0, made.output
    return re.search(r"study (\d+) ready", made.output)[1]


def test_add_list_attempts_remove(run, study_id: str) -> None:
    url = "http://127.0.0.1:9/hook"
    added = run("webhook", "add", "--study", study_id, "--url", url)
    assert added.exit_code == 0, added.output
    hook = re.search(rf"webhook (\d+) for study {study_id}: {re.escape(url)}", added.output)[1]
    assert re.search(r"^secret: whsec_[A-Za-z0-9+/=]{40,}$", added.output, re.M)
    listed = run("webhook", "list", "--study", study_id)
    assert listed.output.strip().split("\t") == [
        hook,
        f"study {study_id}",
        url,
        "0 delivered, 0 pending, 0 failed",
    ]
    assert hook in run("webhook", "list").output
    tried = run("webhook", "attempts", "--webhook", hook)
    assert (tried.exit_code, tried.output) == (0, "")
    assert run("webhook", "remove", "--webhook", hook).output == f"webhook {hook} removed\n"
    assert run("webhook", "list", "--study", study_id).output == ""


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (("--url", "http://example.com/hook"), "a webhook URL must be https"),
        (("--url", "https://10.0.0.1/hook"), "10.0.0.1 is a private address"),
        (("--url", "https://192.168.1.1"), "192.168.1.1 is a private address"),
        (("--url", "https://169.254.169.254/"), "169.254.169.254 is a link-local address"),
        (("--url", "https://8.8.8.8/hook"), "8.8.8.8 is a public address"),
        (("--url", "https://127.0.0.1/", "--survey", "1"), "exactly one of --study and --survey"),
    ],
)
def test_bad_input_exits_2_and_changes_nothing(run, study_id: str, args, says: str) -> None:
    before = run("webhook", "list").output
    result = run("webhook", "add", "--study", study_id, *args)
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("acv: error: ") and says in lines[0]
    assert run("webhook", "list").output == before


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (("webhook", "add", "--study", "999999", "--url", "https://127.0.0.1/"), "study 999999"),
        (("webhook", "remove", "--webhook", "999999"), "webhook 999999 not found"),
        (("webhook", "attempts", "--webhook", "999999"), "webhook 999999 not found"),
        (("webhook", "redeliver", "--webhook", "999999", "--event", "e"), "webhook 999999"),
        (("webhook", "list", "--survey", "999999"), "survey 999999 not found"),
    ],
)
def test_unknown_ids_exit_2(run, args, says: str) -> None:
    result = run(*args)
    assert result.exit_code == 2 and says in result.stderr


def test_redeliver_queues_an_event_again(run, study_id: str, backend_url) -> None:
    """A finished participant's event (no server runs: it waits in the outbox), marked as
    failed, is pending again with a fresh series of attempts; another id is exit 2."""
    hook = re.search(r"webhook (\d+)", run("webhook", "add", "--study", study_id, "--url",
                     "http://127.0.0.1:9/hook").output)[1]  # fmt: skip
    assert run("simulate", "--study", study_id, "--teacher", "standing").exit_code == 0
    engine = create_engine(backend_url[1])
    with engine.begin() as db:
        event = db.execute(select(WebhookEvent.event_id).where(
            WebhookEvent.webhook_id == int(hook), WebhookEvent.type == "participant.finished"
        )).scalar_one()  # fmt: skip
        db.execute(update(WebhookEvent).values(attempts=40))
    done = run("webhook", "redeliver", "--webhook", hook, "--event", event)
    assert done.output == f"event {event} of webhook {hook} queued for delivery\n"
    with engine.begin() as db:
        row = db.execute(select(WebhookEvent).where(WebhookEvent.event_id == event)).one()
    assert (row.attempts, row.delivered_at) == (0, None)
    missing = run("webhook", "redeliver", "--webhook", hook, "--event", "evt_none")
    assert (
        missing.exit_code == 2 and f"event evt_none of webhook {hook} not found" in missing.stderr
    )
    engine.dispose()
