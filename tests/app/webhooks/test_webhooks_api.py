"""Webhooks through the REST API and the study and survey pages' forms (issue 29 §3), on
SQLite and PostgreSQL: events written in the transaction of the change, delivered signed
(verified by the ``standardwebhooks`` package), retried until a receiver that was down is up
(no event lost), each sent once by its id, every attempt logged; bad input refused with a
clear 4xx and nothing changed. Receivers listen on 127.0.0.1 only.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import update

from app.db import writing
from app.models import WebhookEvent
from app.settings import Settings
from app.webhooks.delivery import Policy
from app.webhooks.outbox import Owner, emit
from app.webhooks.scheduler import Deliverer
from tests.support.crowd import configure, joined_player, visitor
from tests.support.studies import Player
from tests.support.surveys import invite as invite_respondents
from tests.support.surveys import paper_answers, paper_body, participant_trees
from tests.support.wait import wait_for
from tests.support.web import ADMIN, CSRF_RE, logged_in
from tests.support.webhooks import Receiver, attempts, events, webhook_settings

REFUSED_LOOPBACK = "webhooks may only go to loopback (ACV_WEBHOOK_TARGETS=loopback) addresses"


@pytest.fixture(scope="module")
def settings(backend_url: tuple[Path, str]) -> Settings:
    """Webhooks to 127.0.0.1 only (the tests' setting) and quick retries."""
    return webhook_settings(backend_url)


def register(client: TestClient, url: str, **owner: int) -> dict[str, Any]:
    response = client.post("/api/webhooks", json={"url": url, **owner}, headers=ADMIN)
    assert response.status_code == 201, response.text
    return response.json()


def remove(client: TestClient, hook: dict[str, Any]) -> None:
    assert client.delete(f"/api/webhooks/{hook['id']}", headers=ADMIN).status_code == 204


def all_delivered(client: TestClient, hook: dict[str, Any], receiver: Receiver) -> list[dict]:
    """Wait until every event of the webhook's outbox is delivered and the receiver holds
    each; returns the outbox."""
    outbox = wait_for(
        lambda: events(client, hook["id"]),
        lambda evs: evs and all(e["status"] == "delivered" for e in evs),
        what="every event delivered",
    )
    assert {e["event_id"] for e in outbox} <= receiver.event_ids()
    return outbox


def of_type(outbox: list[dict], type_: str) -> list[dict[str, Any]]:
    return [e["payload"]["data"] for e in outbox if e["type"] == type_]


def test_a_finished_participant_is_posted_signed_and_logged(
    client: TestClient, study: dict[str, Any], invite: Callable[..., Player]
) -> None:
    with Receiver() as receiver:
        hook = register(client, receiver.url(), study_id=study["id"])
        assert hook["secret"].startswith("whsec_")
        assert (hook["study_id"], hook["survey_id"], hook["pending"]) == (study["id"], None, 0)
        player = invite()
        player.play()
        outbox = all_delivered(client, hook, receiver)
        [finished] = [e for e in outbox if e["type"] == "participant.finished"]
        [delivery] = [d for d in receiver.received() if d.event_id == finished["event_id"]]
        assert delivery.verified(hook["secret"]) == finished["payload"]
        assert delivery.headers["content-type"] == "application/json" and delivery.path == "/hook"
        data = finished["payload"]["data"]
        assert (data["study_id"], data["participant_id"], data["via_link"]) == (
            study["id"],
            player.id,
            False,
        )
        log = attempts(client, hook["id"])
        assert {(a["event_id"], a["status_code"], a["error"]) for a in log} == {
            (e["event_id"], 200, None) for e in outbox
        }
        counted = client.get(f"/api/webhooks/{hook['id']}", headers=ADMIN).json()
        assert (counted["delivered"], counted["pending"], counted["failed"]) == (len(outbox), 0, 0)
    remove(client, hook)


def test_a_receiver_that_is_down_loses_no_event(
    client: TestClient, study: dict[str, Any], invite: Callable[..., Player]
) -> None:
    receiver = Receiver()  # its port is held but nothing listens there yet
    hook = register(client, receiver.url(), study_id=study["id"])
    for _ in range(2):
        invite().play()
    ids = {e["event_id"] for e in events(client, hook["id"])}
    assert len(of_type(events(client, hook["id"]), "participant.finished")) == 2
    failed = wait_for(
        lambda: attempts(client, hook["id"]),
        lambda log: all(sum(a["event_id"] == i for a in log) >= 2 for i in ids),
        what="two failed attempts of each event while the receiver is down",
    )
    assert all(a["status_code"] is None and "ConnectError" in a["error"] for a in failed)
    assert {e["status"] for e in events(client, hook["id"])} == {"pending"}
    with receiver:
        all_delivered(client, hook, receiver)
    assert receiver.event_ids() == ids  # every event arrived, identified by its id
    remove(client, hook)


def test_an_event_is_redelivered_on_request(
    client: TestClient, study: dict[str, Any], invite: Callable[..., Player]
) -> None:
    """A failed event (every attempt used: set here, as 40 attempts would take minutes) is sent
    again once asked, with a fresh series of attempts and its own id; so is a delivered one
    (the receiver gets it twice, and deduplicates by id). Another webhook's event, or none, is
    a 404 that changes nothing."""
    runtime = client.app.state.runtime
    with Receiver() as receiver:
        hook = register(client, receiver.url(), study_id=study["id"])
        invite().play()
        outbox = all_delivered(client, hook, receiver)
        [event] = [e for e in outbox if e["type"] == "participant.finished"]
        path = f"/api/webhooks/{hook['id']}/events/{event['event_id']}/redeliver"
        again = client.post(path, headers=ADMIN)
        assert again.status_code == 200, again.text
        assert (again.json()["attempts"], again.json()["delivered_at"]) == (0, None)
        wait_for(  # received, and logged: the loop's record must not land after the update
            lambda: (
                [d.event_id for d in receiver.received()].count(event["event_id"]),
                _status(client, hook, event),
            ),
            lambda seen: seen == (2, "delivered"),
            what="the delivered event sent again",
        )
        with runtime.sessions() as session, writing(session):
            session.execute(
                update(WebhookEvent)
                .where(WebhookEvent.event_id == event["event_id"])
                .values(attempts=runtime.settings.webhook_max_attempts, delivered_at=None)
            )
        assert _status(client, hook, event) == "failed"
        assert client.post(path, headers=ADMIN).json()["status"] == "pending"
        all_delivered(client, hook, receiver)
    other = register(client, "http://127.0.0.1:9/other", study_id=study["id"])
    for wrong in (
        f"/api/webhooks/{hook['id']}/events/evt_nope/redeliver",
        path.replace(f"/webhooks/{hook['id']}/", f"/webhooks/{other['id']}/"),
        path.replace(f"/webhooks/{hook['id']}/", "/webhooks/999999/"),
    ):
        refused = client.post(wrong, headers=ADMIN)
        assert refused.status_code == 404 and "not found" in refused.json()["detail"], wrong
    assert client.post(path, headers={}).status_code == 401
    assert _status(client, hook, event) == "delivered"  # the refused requests changed nothing
    remove(client, other)
    remove(client, hook)


def _status(client: TestClient, hook: dict[str, Any], event: dict[str, Any]) -> str:
    [found] = [e for e in events(client, hook["id"]) if e["event_id"] == event["event_id"]]
    return found["status"]


def test_two_deliverers_never_send_one_event_twice(
    client: TestClient, study: dict[str, Any]
) -> None:
    """Two more delivery loops on the same database (as two servers would run), beside the
    app's own, claim each event once: one attempt and one delivery per event."""
    runtime = client.app.state.runtime
    with Receiver() as receiver:
        hook = register(client, receiver.url(), study_id=study["id"])
        with runtime.sessions() as session, writing(session):
            for _ in range(30):
                emit(
                    session,
                    owner=Owner("study", study["id"]),
                    type_="test",
                    subject=None,
                    data=dict,
                )
        loops = [Deliverer(runtime.sessions, Policy.of(runtime.settings)) for _ in range(2)]
        with ThreadPoolExecutor(2) as pool:
            list(pool.map(lambda loop: loop.tick(), loops))
        outbox = all_delivered(client, hook, receiver)
    assert len(outbox) == 30
    assert len(attempts(client, hook["id"])) == 30
    assert Counter(d.event_id for d in receiver.received()) == Counter(
        e["event_id"] for e in outbox
    )
    remove(client, hook)


def _consent_and(client: TestClient, slug: str, decision: str, prefix: str = "/s/"):
    page = visitor(client)
    form = page.get(f"{prefix}{slug}")
    assert form.status_code == 200, form.text
    token = CSRF_RE.search(form.text)
    assert token, "no consent form"
    return page, page.post(
        f"{prefix}{slug}", data={"csrf_token": token.group(1), "decision": decision}
    )


def test_declines_flags_and_the_target_are_posted_once(
    client: TestClient, make_study: Callable[..., dict[str, Any]]
) -> None:
    study = make_study()
    link = configure(
        client,
        study["id"],
        max_participants=2,
        consent_text="We keep your choices.",
        speed_threshold_ms=600_000,  # every participant here is "fast"
    )
    with Receiver() as receiver:
        hook = register(client, receiver.url(), study_id=study["id"])
        _, declined = _consent_and(client, link["slug"], "decline")
        assert declined.status_code == 200
        for _ in range(2):
            page, agreed = _consent_and(client, link["slug"], "agree")
            joined_player(client, page, agreed).play()
        outbox = all_delivered(client, hook, receiver)
    assert Counter(e["type"] for e in outbox) == {
        "participant.declined": 1,
        "participant.finished": 2,
        "participant.flagged": 2,
        "study.target_reached": 1,
    }
    sid = study["id"]
    assert of_type(outbox, "participant.declined") == [{"study_id": sid, "declines": 1}]
    assert of_type(outbox, "study.target_reached") == [
        {"study_id": sid, "finished": 2, "max_participants": 2}
    ]
    assert all(
        d["via_link"] and "fast" in d["flags"] for d in of_type(outbox, "participant.finished")
    )
    assert all(
        d["by"] == "finish" and "fast" in d["flags"] for d in of_type(outbox, "participant.flagged")
    )


def test_the_gold_gate_flags_a_participant_once(
    client: TestClient, make_study: Callable[..., dict[str, Any]], invite: Callable[..., Player]
) -> None:
    study = make_study(n_candidates=8, seed=5)
    sid = study["id"]
    gold = [
        client.post(f"/api/studies/{sid}/gold", json=item, headers=ADMIN).json()
        for item in ({"a": 0, "b": 1, "answer": 1}, {"a": 2, "b": 3, "answer": 2})
    ]
    wrong = {g["id"]: ({g["a"], g["b"]} - {g["answer"]}).pop() for g in gold}
    configure(client, sid, gold_gate=0.9, gate_excludes=False, speed_threshold_ms=0)
    with Receiver() as receiver:
        hook = register(client, receiver.url(), study_id=sid)
        careless = invite(sid)
        while (match := careless.next_match()) is not None:
            if match["gold"] is not None:
                item = match["gold"]["item_id"]
                assert careless.answer_gold(item, wrong[item]).status_code == 201
            else:
                sent = careless.label(match["match_id"], match["a"]["candidate_id"])
                assert sent.status_code == 201, sent.text
        configure(client, sid, gold_gate=0.9, gate_excludes=True)  # the gate again: excludes
        outbox = all_delivered(client, hook, receiver)
    [flagged] = [d for d in of_type(outbox, "participant.flagged") if d["by"] == "gold_gate"]
    assert (flagged["participant_id"], flagged["flags"], flagged["excluded"]) == (
        careless.id,
        ["below_gate"],
        False,
    )
    assert flagged["reason"].startswith("gold gate: 0 of 2")


def test_a_survey_posts_its_respondents(client: TestClient, study: dict[str, Any]) -> None:
    trees = participant_trees(client, study["id"])
    survey = client.post("/api/surveys", json=paper_body(*trees), headers=ADMIN).json()
    link = client.put(
        f"/api/surveys/{survey['id']}/crowd",
        json={"enabled": True, "max_participants": 1, "consent_text": "Trees ahead."},
        headers=ADMIN,
    ).json()
    with Receiver() as receiver:
        hook = register(client, receiver.url(), survey_id=survey["id"])
        [person] = invite_respondents(client, survey["id"])
        while (screen := person.screen()) is not None:
            assert person.answer(screen["position"], paper_answers(screen)).status_code == 201
        _consent_and(client, link["slug"], "decline", prefix="/q/")
        outbox = all_delivered(client, hook, receiver)
    assert Counter(e["type"] for e in outbox) == {
        "respondent.finished": 1,
        "respondent.declined": 1,
    }
    [done] = of_type(outbox, "respondent.finished")
    assert (done["survey_id"], done["respondent_id"], done["via_link"]) == (
        survey["id"],
        person.id,
        False,
    )


@pytest.mark.parametrize(
    ("body", "status", "detail"),
    [
        ({"url": "http://example.com/hook"}, 422, "a webhook URL must be https"),
        (
            {"url": "https://10.0.0.1/hook"},
            422,
            f"10.0.0.1 is a private address: {REFUSED_LOOPBACK}",
        ),
        (
            {"url": "https://192.168.1.1"},
            422,
            f"192.168.1.1 is a private address: {REFUSED_LOOPBACK}",
        ),
        (
            {"url": "https://169.254.169.254/latest"},
            422,
            f"169.254.169.254 is a link-local address: {REFUSED_LOOPBACK}",
        ),
        # a public address: the tests send traffic to 127.0.0.1 only, and the setting says so
        ({"url": "https://8.8.8.8/hook"}, 422, f"8.8.8.8 is a public address: {REFUSED_LOOPBACK}"),
        ({"url": "https://127.0.0.1/", "survey_id": 1}, 422, "exactly one of study_id"),
        ({"url": "https://127.0.0.1/", "study_id": 999_999}, 404, "study 999999 not found"),
    ],
)
def test_bad_input_is_refused_and_changes_nothing(
    client: TestClient, study: dict[str, Any], body: dict[str, Any], status: int, detail: str
) -> None:
    before = client.get("/api/webhooks", headers=ADMIN).json()
    response = client.post("/api/webhooks", json={"study_id": study["id"]} | body, headers=ADMIN)
    assert response.status_code == status, response.text
    assert response.headers["content-type"] == "application/json"
    assert detail in str(response.json()["detail"])
    assert client.get("/api/webhooks", headers=ADMIN).json() == before


def test_unknown_webhooks_are_404(client: TestClient) -> None:
    for method, path in [
        ("get", "/api/webhooks/999999"),
        ("delete", "/api/webhooks/999999"),
        ("get", "/api/webhooks/999999/attempts"),
        ("get", "/api/webhooks/999999/events"),
    ]:
        response = client.request(method, path, headers=ADMIN)
        assert response.status_code == 404 and response.json() == {
            "detail": "webhook 999999 not found"
        }
    assert client.get("/api/webhooks", headers={}).status_code == 401


def test_the_study_page_registers_and_removes(client: TestClient, study: dict[str, Any]) -> None:
    """The page's form refuses what the API refuses, with the same words, and changes
    nothing; a good URL is registered, shown with its secret, and removed."""
    page, path = logged_in(client), f"/studies/{study['id']}"
    listed = f"/api/webhooks?study_id={study['id']}"
    section = page.get(path).text.split('id="webhooks"')[1]
    token = CSRF_RE.search(section).group(1)  # type: ignore[union-attr]
    refused = page.post(f"{path}/webhooks", data={"csrf_token": token, "url": "https://10.0.0.1/"})
    assert refused.status_code == 422 and "10.0.0.1 is a private address" in refused.text
    assert client.get(listed, headers=ADMIN).json() == []
    added = page.post(f"{path}/webhooks", data={"csrf_token": token, "url": "http://127.0.0.1:9/x"})
    assert added.status_code == 303 and added.headers["location"] == f"{path}#webhooks"
    [hook] = client.get(listed, headers=ADMIN).json()
    shown = page.get(path).text
    assert "http://127.0.0.1:9/x" in shown and hook["secret"] in shown
    gone = page.post(f"{path}/webhooks/{hook['id']}/delete", data={"csrf_token": token})
    assert gone.status_code == 303
    assert client.get(listed, headers=ADMIN).json() == []
