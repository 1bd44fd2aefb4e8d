"""ACV restarted in the middle of a retry loop loses no webhook event (issue 29 §3), on
SQLite and PostgreSQL: ``acv serve`` in a subprocess makes an event while the receiver is
down and retries it; the server is stopped mid-retry; the receiver, then the server, start
again, and the event arrives with the id it was first sent with. Everything goes to
127.0.0.1 only.
"""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest

from tests.support.labelling import label_bracket, wait_until_prepared
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env
from tests.support.wait import wait_for
from tests.support.web import ADMIN, ADMIN_TOKEN
from tests.support.webhooks import Receiver, attempts, events

pytestmark = [pytest.mark.process, pytest.mark.slow]


def _env(data_dir: Path, url: str) -> dict[str, str]:
    return clean_env(
        ACV_DATA_DIR=str(data_dir),
        DATABASE_URL=url,
        ACV_ADMIN_TOKEN=ADMIN_TOKEN,
        ACV_RUN_WORKER="0",
        ACV_WEBHOOK_TARGETS="loopback",
        ACV_WEBHOOK_BACKOFF_S="0.2",
        ACV_WEBHOOK_BACKOFF_CAP_S="0.5",
    )


def _finish_one(api: httpx.Client) -> int:
    """A ready study with one participant who finished; returns the study's id."""
    study = api.post(
        "/api/studies", json={"name": "restart", "env_id": "Hopper-v5", "n_candidates": 4}
    ).json()
    wait_until_prepared(api, study["id"])
    token = api.post(f"/api/studies/{study['id']}/participants").json()["token"]
    label_bracket(api, token, lambda match: match["a"]["candidate_id"])
    return study["id"]


def test_a_restart_in_the_middle_of_retries_loses_no_event(
    backend_url: tuple[Path, str],
) -> None:
    data_dir, url = backend_url
    env, receiver = _env(data_dir, url), Receiver()  # the receiver is down: nothing listens
    with (
        acv_serve(env, data_dir / "first.log") as base,
        httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api,
    ):
        study_id = _finish_one(api)
        hook = api.post("/api/webhooks", json={"study_id": study_id, "url": receiver.url()})
        assert hook.status_code == 201, hook.text
        hook_id = hook.json()["id"]
        assert events(api, hook_id) == []  # registered after the finish: nothing to send
        second = api.post(f"/api/studies/{study_id}/participants").json()["token"]
        label_bracket(api, second, lambda match: match["b"]["candidate_id"])
        [event] = [e for e in events(api, hook_id) if e["type"] == "participant.finished"]
        wait_for(
            lambda: attempts(api, hook_id),
            lambda log: sum(a["event_id"] == event["event_id"] for a in log) >= 2,
            what="the event retried while the receiver is down",
        )
    # the server is stopped mid-retry; its state is in the database only
    with (
        receiver,
        acv_serve(env, data_dir / "second.log") as base,
        httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api,
    ):
        wait_for(
            lambda: {e["event_id"]: e["status"] for e in events(api, hook_id)},
            lambda states: set(states.values()) == {"delivered"},
            what="every event delivered after the restart",
        )
        log = attempts(api, hook_id)
    assert event["event_id"] in receiver.event_ids()
    mine = [a for a in log if a["event_id"] == event["event_id"]]
    assert mine[0]["status_code"] == 200  # newest first: the delivery
    assert len(mine) >= 3 and all(a["status_code"] is None for a in mine[1:])
