"""When webhook attempts run, and beside what (issue 45 §3): every webhook is a lane of its
own, so that a receiver that never answers makes no other receiver's events wait in line.

- **Bounds**: at most one attempt per webhook in flight, and at most ``B`` in all
  (``ACV_WEBHOOK_CONCURRENCY``, default 8), in each delivering process. A receiver that
  stalls holds its own lane, for at most :data:`~app.webhooks.delivery.ATTEMPT_S` an
  attempt; while fewer than ``B`` receivers stall, every other receiver's events go out as
  soon as they are due.
- **Dispatcher**: one thread looks at the outbox every :attr:`Policy.poll_s
  <app.webhooks.delivery.Policy.poll_s>`, and again as soon as an attempt ends, for the due
  events of webhooks without an attempt in flight. It claims one event per such webhook
  (:func:`~app.webhooks.delivery.claim`: of two processes, one gets it) and starts its
  attempt on a thread of its own, which POSTs, logs the outcome and frees the lane.
- **Order** is not promised: a retried event goes out after newer ones, and each webhook
  gets its events at its own pace. Every event carries its ``timestamp`` and a
  per-collection ``seq`` to order by (:mod:`app.webhooks.outbox`).
- **Stopping** cuts the attempts in flight short: each is logged, and its event is due again
  at once, for the next process. :meth:`DeliveryThread.stop` returns once every thread of
  delivery has ended.

Every state is in the database (:mod:`app.webhooks.delivery`), so delivery stays at least
once per receiver, across restarts. The bounds are per process: two processes delivering
on one database (Compose's web workers) may each hold an attempt for the same webhook.
"""

from __future__ import annotations

import logging
import random
import threading
import time

from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, sessionmaker

from app.models import utcnow
from app.settings import Settings
from app.webhooks.delivery import ATTEMPT_S, Outgoing, Policy, claim, due, post, record

log = logging.getLogger(__name__)
#: The dispatcher thread's name; each attempt's thread is named after it and its webhook.
THREAD_NAME = "acv-webhooks"


class Deliverer:
    """The outbox's delivery in one process: :meth:`run` until :meth:`stop`.

    Args:
        sessions: database sessions.
        policy: targets, retries and the number of attempts in flight at once.
    """

    def __init__(self, sessions: sessionmaker[Session], policy: Policy) -> None:
        self.sessions, self.policy = sessions, policy
        self.rng = random.Random()
        self._stopping = threading.Event()
        self._changed = threading.Event()  # an attempt ended, or stopping: look again
        self._lock = threading.Lock()
        self._lanes: set[int] = set()  # the webhooks with an attempt in flight
        self._threads: list[threading.Thread] = []  # the attempts' threads, until seen ended

    def run(self) -> None:
        """Deliver until :meth:`stop`, then wait for the attempts in flight (cut short). A
        failing look at the outbox (the database away) is logged and the loop goes on."""
        while not self._stopping.is_set():
            self._changed.clear()
            try:
                started = self.dispatch()
            except Exception:
                log.exception("webhook delivery failed; trying again")
                started = 0
            if not started:
                self._changed.wait(self.policy.poll_s)
        self.join()

    def tick(self) -> int:
        """Deliver what is due until nothing due is left to start and no attempt is in flight
        (a run's work, once: for tests); returns how many attempts were started."""
        started = 0
        while True:
            self._changed.clear()
            now = self.dispatch()
            started += now
            if not now:
                with self._lock:
                    if not self._lanes:
                        return started
                self._changed.wait(self.policy.poll_s)

    def stop(self) -> None:
        """Start no attempt more, and cut short those in flight."""
        self._stopping.set()
        self._changed.set()

    def dispatch(self) -> int:
        """Claim and start one due event for each webhook without an attempt in flight, the
        longest waiting first, while fewer than ``policy.concurrency`` are in flight; returns
        how many attempts were started."""
        with self._lock:
            busy = set(self._lanes)
        free = self.policy.concurrency - len(busy)
        if free <= 0 or self._stopping.is_set():
            return 0
        with self.sessions() as session:
            pending = due(session, now=utcnow(), policy=self.policy, skip=busy)
        started = 0
        for event_pk, webhook_id in pending:
            if started == free or self._stopping.is_set():
                break
            if webhook_id in busy:  # in flight, or tried in this look (a claim another
                continue  # process won: that process is likely delivering to it now)
            busy.add(webhook_id)
            with self.sessions() as session:
                event = claim(session, event_pk=event_pk, now=utcnow())
            if event is not None:
                self._start(webhook_id, event)
                started += 1
        return started

    def threads(self) -> list[threading.Thread]:
        """The attempts' threads still alive."""
        with self._lock:
            return [thread for thread in self._threads if thread.is_alive()]

    def join(self, timeout_s: float = ATTEMPT_S) -> None:
        """Wait for the attempts in flight to end, ``timeout_s`` at most in all."""
        deadline = time.monotonic() + timeout_s
        for thread in self.threads():
            thread.join(max(0.0, deadline - time.monotonic()))

    def _start(self, webhook_id: int, event: Outgoing) -> None:
        thread = threading.Thread(
            target=self._attempt,
            args=(webhook_id, event),
            name=f"{THREAD_NAME}: webhook {webhook_id}",
            daemon=True,
        )
        with self._lock:
            self._lanes.add(webhook_id)
            self._threads = [t for t in self._threads if t.is_alive()] + [thread]
        try:
            thread.start()
        except BaseException:  # no thread: the lane is free, the event due when its lease ends
            self._free(webhook_id)
            raise

    def _attempt(self, webhook_id: int, event: Outgoing) -> None:
        """POST the event, log the outcome, free the webhook's lane."""
        try:
            outcome = post(event, targets=self.policy.targets, stop=self._stopping)
            with self.sessions() as session:
                try:
                    record(session, event, outcome, policy=self.policy, rng=self.rng)
                except IntegrityError:  # the webhook was removed meanwhile, with its events
                    log.info("webhook event %s: removed during its delivery", event.event_id)
        except Exception:  # the database away: the event is due again when its lease ends
            log.exception("webhook event %s: its attempt was not logged", event.event_id)
        finally:
            self._free(webhook_id)

    def _free(self, webhook_id: int) -> None:
        with self._lock:
            self._lanes.discard(webhook_id)
        self._changed.set()


class DeliveryThread:
    """A :class:`Deliverer` on a daemon thread (started with the web server)."""

    def __init__(self, deliverer: Deliverer) -> None:
        self.deliverer = deliverer
        self._thread = threading.Thread(target=deliverer.run, name=THREAD_NAME, daemon=True)

    def start(self) -> DeliveryThread:
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop delivering: the attempts in flight are cut short and logged. Returns once
        every thread of delivery has ended (after :data:`ATTEMPT_S` at most: a shutdown never
        hangs on a receiver, nor on a database that does not answer)."""
        self.deliverer.stop()
        self._thread.join(timeout=ATTEMPT_S)

    def threads(self) -> list[threading.Thread]:
        """The threads of delivery still alive: the dispatcher and the attempts."""
        alive = [self._thread, *self.deliverer.threads()]
        return [thread for thread in alive if thread.is_alive()]


def start_delivery(sessions: sessionmaker[Session], settings: Settings) -> DeliveryThread:
    """Start delivering webhooks in the background of this process."""
    return DeliveryThread(Deliverer(sessions, Policy.of(settings))).start()
