"""Labels for reuse (issue 14): one row per label, as JSONL, CSV and Parquet.

Each row names the study, the participant and their external ids, its ``kind`` (``bracket``,
or ``disagreement`` for a pair asked after the bracket, which has no match id or round:
:mod:`app.labelling.disagreement`), the match and its round,
the candidates shown on the left and on the right, the winner and the side chosen, the
response time, when the pair was shown and when it was labelled, and ``tie`` (the
participant could not tell; the winner is then the seeded coin's), and ``stimulus``: what
the pair showed, ``still`` (the pictures) or ``clip`` (motion clips, issue 41 §3), as stored
with the bracket label or the disagreement pair's answer. ``shown_at`` is
``labelled_at`` minus the response time (the page measures that from both pictures being
on screen), so it is empty when no response time was stored. Per participant, their quality
flags, reliability and gold answers (:mod:`app.labelling.quality`) ride along, and whether
the researcher excluded them: excluded participants' labels are left out unless asked for
(``include_excluded``), and never deleted.
"""

from __future__ import annotations

import io
import json
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import ColumnElement, select
from sqlalchemy.orm import Session

from app.core import csv_export
from app.labelling import study_link
from app.labelling.quality import quality
from app.models import DisagreementPair, Label, Match, OpenLink, Participant, as_utc, utcnow
from app.recruiting import seats
from app.recruiting import service as recruiting
from app.recruiting.seats import kept_in_data
from app.studies.service import get_study

COLUMNS = (
    "study_id",
    "participant_id",
    "external_id",
    "external_ids",
    "kind",
    "match_id",
    "round",
    "left",
    "right",
    "winner",
    "side",
    "response_ms",
    "shown_at",
    "labelled_at",
    "flags",
    "tie",
    "stimulus",
    "reliability",
    "gold_right",
    "gold_asked",
    "excluded",
    "outcome",
    "code",
)
People = dict[int, dict[str, Any]]
"""Participant id -> the columns that describe them, not the label: ``flags``,
``reliability``, ``gold_right`` and ``gold_asked`` (gold items answered right, and
answered), ``excluded``."""


def _side(chose_left: bool | None) -> str | None:
    return None if chose_left is None else ("left" if chose_left else "right")


def records(
    session: Session, *, study_id: int, include_excluded: bool = False
) -> list[dict[str, Any]]:
    """Every label of the study, in label order, as :data:`COLUMNS` dicts; excluded
    participants' labels only with ``include_excluded``."""
    get_study(session, study_id=study_id)
    link, now = recruiting.settings(session, study_link.LINK, study_id), utcnow()
    people: People = {
        q.participant.id: {
            "flags": q.flags,
            "reliability": q.reliability,
            "gold_right": q.gold.right,
            "gold_asked": q.gold.asked,
            "excluded": q.participant.excluded,
            **_outcome(q.participant, link, now),
        }
        for q in quality(session, study_id=study_id).participants
    }
    kept = _kept(study_id, include_excluded)
    rows = session.execute(
        select(
            Label.participant_id,
            Participant.external_id,
            Participant.external_ids,
            Label.match_id,
            Match.round,
            Match.a,
            Match.b,
            Match.a_left,
            Label.winner,
            Label.chose_left,
            Label.response_ms,
            Label.created_at,
            Label.tie,
            Label.stimulus,
        )
        .join(Match, Match.id == Label.match_id)
        .join(Participant, Participant.id == Label.participant_id)
        .where(*kept)
        .order_by(Label.id)
    )
    out = [
        _record(study_id, people, "bracket", pid, ext, ext_ids, mid, rnd, a, b, a_left, w, ms, at)
        | {"side": _side(chose_left), "tie": bool(tie), "stimulus": stim}  # side None: old
        for pid, ext, ext_ids, mid, rnd, a, b, a_left, w, chose_left, ms, at, tie, stim in rows
    ]
    return out + _pair_records(session, study_id, people, kept)


def _kept(study_id: int, include_excluded: bool) -> list[ColumnElement[bool]]:
    """The conditions on ``Participant`` of the labels exported."""
    return [
        Participant.study_id == study_id,
        *kept_in_data(include_excluded=include_excluded, now=utcnow()),
    ]


def _outcome(person: Participant, link: OpenLink | None, now: datetime) -> dict[str, Any]:
    """The participant's outcome and the open link's code for it (issue 45 §2)."""
    failed_gate = person.gate_stopped_at is not None
    result = seats.outcome(person, link, now, failed_gate=failed_gate)
    return {"outcome": result.name, "code": result.code}


def _pair_records(
    session: Session, study_id: int, people: People, kept: list[ColumnElement[bool]]
) -> list[dict[str, Any]]:
    """The answered disagreement pairs, by participant and position."""
    rows = session.execute(
        select(
            DisagreementPair.participant_id,
            Participant.external_id,
            Participant.external_ids,
            DisagreementPair.a,
            DisagreementPair.b,
            DisagreementPair.a_left,
            DisagreementPair.winner,
            DisagreementPair.response_ms,
            DisagreementPair.answered_at,
            DisagreementPair.stimulus,
        )
        .join(Participant, Participant.id == DisagreementPair.participant_id)
        .where(*kept, DisagreementPair.winner.is_not(None))
        .order_by(DisagreementPair.participant_id, DisagreementPair.position)
    )
    return [
        _record(
            study_id, people, "disagreement", pid, ext, ids, None, None, a, b, a_left, w, ms, at
        )
        | {"stimulus": stim}
        for pid, ext, ids, a, b, a_left, w, ms, at, stim in rows
    ]


def _record(
    study_id: int,
    people: People,
    kind: str,
    pid: int,
    ext: str | None,
    ext_ids: dict[str, str] | None,
    mid: int | None,
    rnd: int | None,
    a: int,
    b: int,
    a_left: bool,
    winner: int,
    ms: int | None,
    at: datetime,
) -> dict[str, Any]:
    """One row of :data:`COLUMNS`."""
    labelled = as_utc(at)
    shown = None if ms is None else labelled - timedelta(milliseconds=ms)
    left = a if a_left else b
    return {
        "study_id": study_id,
        "participant_id": pid,
        "external_id": ext,
        "external_ids": ext_ids or {},
        "kind": kind,
        "match_id": mid,
        "round": rnd,
        "left": left,
        "right": b if a_left else a,
        "winner": winner,
        "side": "left" if winner == left else "right",
        "response_ms": ms,
        "shown_at": None if shown is None else shown.isoformat(),
        "labelled_at": labelled.isoformat(),
        "tie": False,  # a disagreement pair is always decided (a bracket label's is its own)
        "stimulus": "still",  # the caller puts the pair's stored stimulus here
        **people[pid],
    }


def to_jsonl(rows: list[dict[str, Any]]) -> str:
    return "".join(json.dumps(r, sort_keys=False) + "\n" for r in rows)


def to_csv(rows: list[dict[str, Any]]) -> str:
    """CSV with a header; ``external_ids`` as a JSON object, ``flags`` joined by ``;``."""
    return csv_export.csv_text(
        COLUMNS,
        (
            {
                **r,
                "external_ids": json.dumps(r["external_ids"], sort_keys=True),
                "flags": ";".join(r["flags"]),
            }
            for r in rows
        ),
    )


def to_parquet(rows: list[dict[str, Any]]) -> bytes:
    """A Parquet file that ``datasets.load_dataset("parquet", ...)`` reads: flat typed
    columns, ``external_ids`` as a JSON string (its keys differ between studies)."""
    import pyarrow as pa  # imported here: only this export needs it
    import pyarrow.parquet as pq

    schema = pa.schema(
        [
            ("study_id", pa.int64()),
            ("participant_id", pa.int64()),
            ("external_id", pa.string()),
            ("external_ids", pa.string()),
            ("kind", pa.string()),
            ("match_id", pa.int64()),
            ("round", pa.int64()),
            ("left", pa.int64()),
            ("right", pa.int64()),
            ("winner", pa.int64()),
            ("side", pa.string()),
            ("response_ms", pa.int64()),
            ("shown_at", pa.string()),
            ("labelled_at", pa.string()),
            ("flags", pa.list_(pa.string())),
            ("tie", pa.bool_()),
            ("stimulus", pa.string()),
            ("reliability", pa.float64()),
            ("gold_right", pa.int64()),
            ("gold_asked", pa.int64()),
            ("excluded", pa.bool_()),
            ("outcome", pa.string()),
            ("code", pa.string()),
        ]
    )
    flat = [{**r, "external_ids": json.dumps(r["external_ids"], sort_keys=True)} for r in rows]
    table = pa.Table.from_pylist(flat, schema=schema)
    buffer = io.BytesIO()
    pq.write_table(table, buffer)
    return buffer.getvalue()
