"""Delivering the outbox: a background loop that claims due events, POSTs each, signed, to
its webhook, logs the attempt, and marks it delivered (a 2xx) or retries it later.

- **Due**: not delivered, ``next_attempt_at`` passed, fewer than the allowed attempts.
- **Claim**: ``UPDATE ... SET next_attempt_at = now + lease WHERE id = ? AND next_attempt_at
  <= now AND delivered_at IS NULL``: of two processes (``acv serve`` twice on one database)
  only one updates the row. The lease also resumes a delivery its process died in: the
  event is due again when the lease ends. All state is in the database, so a restarted
  server goes on where the last one stopped.
- **Attempt**: the URL is checked again (:mod:`app.webhooks.targets`) and the request goes
  to the address checked, not to a second lookup; redirects are never followed, proxies
  from the environment never used, and the answer's body never read. An attempt ends after
  :data:`ATTEMPT_S` in all, whatever the receiver does: httpx's timeouts bound each read,
  so a receiver trickling its headers a byte at a time would otherwise hold the loop.
- **Retry**: exponential backoff with jitter, ``ACV_WEBHOOK_BACKOFF_S * 2**(n - 1)`` capped
  at ``ACV_WEBHOOK_BACKOFF_CAP_S``; after ``ACV_WEBHOOK_MAX_ATTEMPTS`` the event is failed.

Delivery is at least once: a receiver that answered 2xx after the attempt's timeout, or a
process that died between the request and its log, gets the event again, with the same
``webhook-id``; receivers deduplicate by it.
"""

from __future__ import annotations

import json
import logging
import random
import threading
import time
from dataclasses import dataclass
from datetime import datetime, timedelta

import anyio
import httpx
from sqlalchemy import select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, sessionmaker

from app.db import writing
from app.models import Webhook, WebhookAttempt, WebhookEvent, utcnow
from app.settings import Settings
from app.webhooks import signing
from app.webhooks.targets import Target, Targets, check_url
from engine.errors import InputError

log = logging.getLogger(__name__)
#: Seconds each step of an attempt may take (connecting, one write, one read).
TIMEOUT_S = 5.0
#: Seconds one attempt may take in all (connecting, sending, the answer's headers).
ATTEMPT_S = 10.0
#: Seconds a claimed event belongs to its claimer; past this another process may retry it.
LEASE_S = 60.0
#: Events claimed per look at the outbox.
BATCH = 20
USER_AGENT = "ACV-Webhooks/1"


@dataclass(frozen=True)
class Policy:
    """Where webhooks may go and how failed deliveries are retried (from :class:`Settings`)."""

    targets: Targets = "public"
    backoff_s: float = 5.0
    backoff_cap_s: float = 3600.0
    max_attempts: int = 40

    @classmethod
    def of(cls, settings: Settings) -> Policy:
        return cls(
            settings.webhook_targets,
            settings.webhook_backoff_s,
            settings.webhook_backoff_cap_s,
            settings.webhook_max_attempts,
        )

    @property
    def poll_s(self) -> float:
        """Seconds between two looks at an idle outbox."""
        return min(1.0, self.backoff_s)

    def backoff(self, attempts: int, rng: random.Random) -> timedelta:
        """The wait after the ``attempts``-th failure: exponential, capped, and drawn
        between half and all of it, so that a receiver's backlog does not come back at once."""
        full = min(self.backoff_cap_s, self.backoff_s * 2 ** min(attempts - 1, 60))
        return timedelta(seconds=full * (0.5 + rng.random() / 2))


@dataclass(frozen=True)
class Outgoing:
    """A claimed event and where it goes."""

    id: int
    event_id: str
    attempts: int
    payload: dict
    url: str
    secret: str


@dataclass(frozen=True)
class Outcome:
    """What an attempt got: the receiver's status, or why there was none."""

    status_code: int | None
    error: str | None
    duration_ms: int

    @property
    def delivered(self) -> bool:
        return self.status_code is not None and 200 <= self.status_code < 300


def due(session: Session, *, now: datetime, policy: Policy) -> list[int]:
    """Events to attempt now, the longest waiting first."""
    return list(
        session.scalars(
            select(WebhookEvent.id)
            .where(
                WebhookEvent.delivered_at.is_(None),
                WebhookEvent.next_attempt_at <= now,
                WebhookEvent.attempts < policy.max_attempts,
            )
            .order_by(WebhookEvent.next_attempt_at)
            .limit(BATCH)
        )
    )


def claim(session: Session, *, event_pk: int, now: datetime) -> Outgoing | None:
    """Take the event for one lease, or ``None`` when another process took it first."""
    with writing(session):
        taken = session.execute(
            update(WebhookEvent)
            .where(
                WebhookEvent.id == event_pk,
                WebhookEvent.delivered_at.is_(None),
                WebhookEvent.next_attempt_at <= now,
            )
            .values(next_attempt_at=now + timedelta(seconds=LEASE_S))
        ).rowcount  # type: ignore[attr-defined]
        if not taken:
            return None
        row = session.execute(
            select(
                WebhookEvent.id,
                WebhookEvent.event_id,
                WebhookEvent.attempts,
                WebhookEvent.payload,
                Webhook.url,
                Webhook.secret,
            )
            .join(Webhook, Webhook.id == WebhookEvent.webhook_id)
            .where(WebhookEvent.id == event_pk)
        ).one()
    return Outgoing(*row)


def post(event: Outgoing, *, targets: Targets, deadline_s: float = ATTEMPT_S) -> Outcome:
    """One signed ``POST`` of the event to its checked address, over within ``deadline_s``."""
    started = time.monotonic()
    try:
        target = check_url(event.url, targets=targets)
        status, error = anyio.run(_send, target, event, deadline_s), None
    except InputError as exc:
        status, error = None, f"refused: {exc}"
    except TimeoutError:
        status, error = None, f"no answer within {deadline_s:g} s"
    except Exception as exc:  # noqa: BLE001  # any failure is this attempt's, logged and retried
        status, error = None, f"{type(exc).__name__}: {exc}"[:500]
    if status is not None and 300 <= status < 400:
        error = "redirects are not followed"
    return Outcome(status, error, round((time.monotonic() - started) * 1000))


async def _send(target: Target, event: Outgoing, deadline_s: float) -> int:
    """POST the event and return the answer's status; cancelled at ``deadline_s``.

    One client per attempt, with no kept-alive connections: a pool keyed by address would let
    two hosts behind one address share a TLS connection, whose certificate was checked for
    the first only.
    """
    body = json.dumps(event.payload, separators=(",", ":"), ensure_ascii=False).encode()
    headers = {
        "Host": target.host_header,
        "Content-Type": "application/json",
        "User-Agent": USER_AGENT,
        **signing.headers(
            event.secret, msg_id=event.event_id, timestamp=int(time.time()), body=body
        ),
    }
    # TLS checks the certificate against the registered name while connecting to the address
    extensions = {"sni_hostname": target.host} if target.scheme == "https" else {}
    with anyio.fail_after(deadline_s):
        async with httpx.AsyncClient(
            timeout=TIMEOUT_S, follow_redirects=False, trust_env=False
        ) as client:
            request = client.build_request(
                "POST", target.pinned_url, content=body, headers=headers, extensions=extensions
            )
            response = await client.send(request, stream=True)  # the body is never read
            await response.aclose()
    return response.status_code


def record(
    session: Session, event: Outgoing, outcome: Outcome, *, policy: Policy, rng: random.Random
) -> None:
    """Log the attempt; mark the event delivered, or due again after its backoff."""
    now, attempts = utcnow(), event.attempts + 1
    values: dict[str, object] = {"attempts": WebhookEvent.attempts + 1}
    if outcome.delivered:
        values["delivered_at"] = now
    else:
        values["next_attempt_at"] = now + policy.backoff(attempts, rng)
    with writing(session):
        session.add(
            WebhookAttempt(
                event_id=event.id,
                attempted_at=now,
                status_code=outcome.status_code,
                error=outcome.error,
                duration_ms=outcome.duration_ms,
            )
        )
        session.execute(update(WebhookEvent).where(WebhookEvent.id == event.id).values(values))


class Deliverer:
    """The delivery loop of one process: :meth:`tick` until stopped.

    Args:
        sessions: database sessions.
        policy: targets and retries.
    """

    def __init__(self, sessions: sessionmaker[Session], policy: Policy) -> None:
        self.sessions, self.policy = sessions, policy
        self.rng = random.Random()

    def tick(self, stop: threading.Event | None = None) -> int:
        """Attempt the due events once each; returns how many were attempted."""
        with self.sessions() as session:
            pending = due(session, now=utcnow(), policy=self.policy)
        done = 0
        for event_pk in pending:
            if stop is not None and stop.is_set():
                break
            with self.sessions() as session:
                event = claim(session, event_pk=event_pk, now=utcnow())
            if event is None:
                continue
            outcome = post(event, targets=self.policy.targets)
            with self.sessions() as session:
                try:
                    record(session, event, outcome, policy=self.policy, rng=self.rng)
                except IntegrityError:  # the webhook was removed meanwhile, with its events
                    log.info("webhook event %s: removed during its delivery", event.event_id)
            done += 1
        return done

    def run(self, stop: threading.Event) -> None:
        """Deliver until ``stop`` is set; a failing tick (the database away) is logged and
        the loop goes on."""
        while not stop.is_set():
            try:
                done = self.tick(stop)
            except Exception:
                log.exception("webhook delivery failed; trying again")
                done = 0
            stop.wait(0 if done else self.policy.poll_s)


class DeliveryThread:
    """A :class:`Deliverer` on a daemon thread (started with the web server)."""

    def __init__(self, deliverer: Deliverer) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=deliverer.run, args=(self._stop,), name="acv-webhooks", daemon=True
        )

    def start(self) -> DeliveryThread:
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop after the attempt in flight (at most :data:`ATTEMPT_S`)."""
        self._stop.set()
        self._thread.join(timeout=ATTEMPT_S)  # never hang a shutdown on a slow receiver


def start_delivery(sessions: sessionmaker[Session], settings: Settings) -> DeliveryThread:
    """Start delivering webhooks in the background of this process."""
    return DeliveryThread(Deliverer(sessions, Policy.of(settings))).start()
