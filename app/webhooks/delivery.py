"""Delivering one outbox event: find the due events, claim one, POST it, signed, to its
webhook, log the attempt, and mark it delivered (a 2xx) or due again later. When and side by
side with what the attempts run is :mod:`app.webhooks.scheduler`'s.

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
  so a receiver trickling its headers a byte at a time would otherwise hold the attempt.
  Delivery stopping (the server shutting down) ends it at once: it is logged, and the event
  is due again at once, for the next process.
- **Retry**: exponential backoff with jitter, ``ACV_WEBHOOK_BACKOFF_S * 2**(n - 1)`` capped
  at ``ACV_WEBHOOK_BACKOFF_CAP_S``; after ``ACV_WEBHOOK_MAX_ATTEMPTS`` the event is failed.

Delivery is at least once: a receiver that answered 2xx after the attempt's timeout, or a
process that died (or stopped) between the request and its log, gets the event again, with
the same ``webhook-id``; receivers deduplicate by it.
"""

from __future__ import annotations

import functools
import json
import random
import ssl
import threading
import time
from collections.abc import Collection
from dataclasses import dataclass
from datetime import datetime, timedelta

import anyio
import httpx
from sqlalchemy import select, update
from sqlalchemy.orm import Session

from app.db import writing
from app.models import Webhook, WebhookAttempt, WebhookEvent, utcnow
from app.settings import Settings
from app.webhooks import signing
from app.webhooks.targets import Target, Targets, check_url
from engine.errors import InputError

#: Seconds each step of an attempt may take (connecting, one write, one read).
TIMEOUT_S = 5.0
#: Seconds one attempt may take in all (connecting, sending, the answer's headers).
ATTEMPT_S = 10.0
#: Seconds a claimed event belongs to its claimer; past this another process may retry it.
LEASE_S = 60.0
#: Due events read per look at the outbox.
BATCH = 20
#: Seconds at most between two looks at an idle outbox: how late a new event may be seen.
IDLE_POLL_S = 0.25
#: Seconds between two checks, during an attempt, of whether delivery is stopping.
STOP_CHECK_S = 0.05
USER_AGENT = "ACV-Webhooks/1"


@dataclass(frozen=True)
class Policy:
    """Where webhooks may go, how failed deliveries are retried, and how many attempts run
    at once (from :class:`Settings`)."""

    targets: Targets = "public"
    backoff_s: float = 5.0
    backoff_cap_s: float = 3600.0
    max_attempts: int = 40
    #: Attempts in flight at once in one process, at most one per webhook.
    concurrency: int = 8

    @classmethod
    def of(cls, settings: Settings) -> Policy:
        return cls(
            settings.webhook_targets,
            settings.webhook_backoff_s,
            settings.webhook_backoff_cap_s,
            settings.webhook_max_attempts,
            settings.webhook_concurrency,
        )

    @property
    def poll_s(self) -> float:
        """Seconds between two looks at an idle outbox (at most :data:`IDLE_POLL_S`)."""
        return min(IDLE_POLL_S, self.backoff_s)

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
    #: Cut short because delivery stopped: due again at once, with no backoff.
    interrupted: bool = False

    @property
    def delivered(self) -> bool:
        return self.status_code is not None and 200 <= self.status_code < 300


class Interrupted(Exception):
    """An attempt cut short because delivery is stopping."""


def due(
    session: Session, *, now: datetime, policy: Policy, skip: Collection[int] = ()
) -> list[tuple[int, int]]:
    """Events to attempt now, the longest waiting first, as ``(event, webhook)`` ids.

    Args:
        skip: webhooks whose events are left out (those with an attempt in flight).
    """
    query = select(WebhookEvent.id, WebhookEvent.webhook_id).where(
        WebhookEvent.delivered_at.is_(None),
        WebhookEvent.next_attempt_at <= now,
        WebhookEvent.attempts < policy.max_attempts,
    )
    if skip:
        query = query.where(WebhookEvent.webhook_id.not_in(skip))
    rows = session.execute(query.order_by(WebhookEvent.next_attempt_at).limit(BATCH))
    return [(event, webhook) for event, webhook in rows]


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


def post(
    event: Outgoing,
    *,
    targets: Targets,
    deadline_s: float = ATTEMPT_S,
    stop: threading.Event | None = None,
) -> Outcome:
    """One signed ``POST`` of the event to its checked address, over within ``deadline_s``,
    or as soon as ``stop`` is set."""
    started, interrupted = time.monotonic(), False
    try:
        target = check_url(event.url, targets=targets)
        status, error = anyio.run(_send, target, event, deadline_s, stop), None
    except InputError as exc:
        status, error = None, f"refused: {exc}"
    except TimeoutError:
        status, error = None, f"no answer within {deadline_s:g} s"
    except Interrupted:
        status, error, interrupted = None, "stopped: delivery shut down during the attempt", True
    except Exception as exc:  # noqa: BLE001  # any failure is this attempt's, logged and retried
        status, error = None, f"{type(exc).__name__}: {exc}"[:500]
    if status is not None and 300 <= status < 400:
        error = "redirects are not followed"
    return Outcome(status, error, round((time.monotonic() - started) * 1000), interrupted)


async def _send(
    target: Target, event: Outgoing, deadline_s: float, stop: threading.Event | None
) -> int:
    """POST the event and return the answer's status; cancelled at ``deadline_s``.

    Raises:
        Interrupted: ``stop`` was set first.
    """
    answer: int | Exception = Interrupted()
    with anyio.fail_after(deadline_s):
        async with anyio.create_task_group() as group:
            if stop is not None:
                group.start_soon(_cancel_when_set, stop, group.cancel_scope)
            try:
                answer = await _request(target, event)
            except Exception as exc:  # noqa: BLE001  # raised below, outside the task group
                answer = exc
            group.cancel_scope.cancel()  # the watcher's, once the request is over
    if isinstance(answer, Exception):
        raise answer
    return answer


async def _cancel_when_set(stop: threading.Event, scope: anyio.CancelScope) -> None:
    while not stop.is_set():
        await anyio.sleep(STOP_CHECK_S)
    scope.cancel()


async def _request(target: Target, event: Outgoing) -> int:
    """POST the event and return the answer's status.

    One client per attempt, with no kept-alive connections: a pool keyed by address would let
    two hosts behind one address share a TLS connection, whose certificate was checked for
    the first only. The clients share one TLS context (the trusted certificates, no
    connection): building it is most of a new client's cost.
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
    async with httpx.AsyncClient(
        verify=tls_context(), timeout=TIMEOUT_S, follow_redirects=False, trust_env=False
    ) as client:
        request = client.build_request(
            "POST", target.pinned_url, content=body, headers=headers, extensions=extensions
        )
        response = await client.send(request, stream=True)  # the body is never read
        await response.aclose()
    return response.status_code


@functools.cache
def tls_context() -> ssl.SSLContext:
    """The TLS settings of every attempt: httpx's defaults (certifi's certificates, the
    host name checked), built once."""
    return httpx.create_ssl_context(trust_env=False)


def record(
    session: Session, event: Outgoing, outcome: Outcome, *, policy: Policy, rng: random.Random
) -> None:
    """Log the attempt; mark the event delivered, or due again: after its backoff, or at once
    when delivery stopped during the attempt."""
    now, attempts = utcnow(), event.attempts + 1
    values: dict[str, object] = {"attempts": WebhookEvent.attempts + 1}
    if outcome.delivered:
        values["delivered_at"] = now
    elif outcome.interrupted:
        values["next_attempt_at"] = now
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
