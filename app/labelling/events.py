"""A study participant's webhook events (issue 29 §3), written in the transaction of the
change they report:

- ``participant.finished`` when the bracket's last label is stored (:mod:`app.labelling.flow`),
  with the participant's own flags then, and ``study.target_reached`` when that makes the
  open link's finished participants reach its maximum (:mod:`app.recruiting.events`);
- ``participant.flagged`` when a participant is flagged: at finish, by the flags their own
  labels give (``position_bias``, ``fast``: the quality table's rules, cheap on at most 127
  labels), and when the gold gate flags them (``below_gate``, by
  :func:`app.labelling.quality.apply_gate` after a gold answer or a new gate, in the
  transaction that excludes them when the gate excludes). The consistency check comes after
  the bracket and raises no event. Each flagging is sent once per participant: at finish
  once, by the gate once.

With no webhook on the study, finishing costs one indexed query more, nothing else.
"""

from __future__ import annotations

import statistics

from sqlalchemy import Connection, select

from app.labelling.participant_quality import flags_of, is_fast
from app.labelling.participants import ParticipantKey
from app.labelling.study_link import LINK
from app.models import CrowdSettings, Label
from app.recruiting import events
from app.studies.crowd import DEFAULT_SPEED_THRESHOLD_MS
from app.webhooks.outbox import Owner, webhook_ids


def finished(conn: Connection, *, participant: ParticipantKey) -> None:
    """The participant just finished their bracket (inside :func:`flow._submit`'s
    transaction): ``participant.finished`` with their flags, ``participant.flagged`` if
    they have any, and the study's target event if it is reached."""
    owner = Owner("study", participant.study_id)
    if not webhook_ids(conn, owner):
        return
    flags = own_flags(conn, participant=participant)
    events.finished(
        conn,
        LINK,
        member_id=participant.id,
        owner_id=participant.study_id,
        extra=lambda: {"flags": flags},
    )
    if flags:
        events.flagged(
            conn,
            LINK,
            member_id=participant.id,
            owner_id=participant.study_id,
            by="finish",
            data={"flags": flags},
        )


def own_flags(conn: Connection, *, participant: ParticipantKey) -> list[str]:
    """``position_bias`` and ``fast``, by the rules of :mod:`app.labelling.quality`."""
    rows = conn.execute(
        select(Label.chose_left, Label.response_ms).where(Label.participant_id == participant.id)
    ).all()
    threshold = conn.scalar(
        select(CrowdSettings.speed_threshold_ms).where(
            CrowdSettings.study_id == participant.study_id
        )
    )
    sided = [left for left, _ in rows if left is not None]
    times = [ms for _, ms in rows if ms is not None]
    median = float(statistics.median(times)) if times else None
    limit = DEFAULT_SPEED_THRESHOLD_MS if threshold is None else threshold
    return flags_of(left=sum(sided), sided=len(sided), fast=is_fast(median, limit))
