"""Labels for reuse (issue 14): one row per label, as JSONL, CSV and Parquet.

Each row names the study, the participant and their external ids, the match and its round,
the candidates shown on the left and on the right, the winner and the side chosen, the
response time, when the pair was shown and when it was labelled. ``shown_at`` is
``labelled_at`` minus the response time (the page measures that from both pictures being
on screen), so it is empty when no response time was stored. Quality flags
(:mod:`app.services.crowd_stats`) ride along per participant.
"""

from __future__ import annotations

import io
import json
from datetime import timedelta
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.models import Label, Match, Participant, as_utc
from app.services import csv_export
from app.services.crowd_stats import quality
from app.services.studies import get_study

COLUMNS = (
    "study_id",
    "participant_id",
    "external_id",
    "external_ids",
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
)


def _side(chose_left: bool | None) -> str | None:
    return None if chose_left is None else ("left" if chose_left else "right")


def records(session: Session, *, study_id: int) -> list[dict[str, Any]]:
    """Every label of the study, in label order, as :data:`COLUMNS` dicts."""
    get_study(session, study_id=study_id)
    flags = {q.participant.id: q.flags for q in quality(session, study_id=study_id).participants}
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
        )
        .join(Match, Match.id == Label.match_id)
        .join(Participant, Participant.id == Label.participant_id)
        .where(Participant.study_id == study_id)
        .order_by(Label.id)
    )
    out = []
    for pid, ext, ext_ids, mid, rnd, a, b, a_left, winner, chose_left, ms, at in rows:
        labelled = as_utc(at)
        shown = None if ms is None else labelled - timedelta(milliseconds=ms)
        out.append(
            {
                "study_id": study_id,
                "participant_id": pid,
                "external_id": ext,
                "external_ids": ext_ids or {},
                "match_id": mid,
                "round": rnd,
                "left": a if a_left else b,
                "right": b if a_left else a,
                "winner": winner,
                "side": _side(chose_left),
                "response_ms": ms,
                "shown_at": None if shown is None else shown.isoformat(),
                "labelled_at": labelled.isoformat(),
                "flags": flags.get(pid, []),
            }
        )
    return out


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
        ]
    )
    flat = [{**r, "external_ids": json.dumps(r["external_ids"], sort_keys=True)} for r in rows]
    table = pa.Table.from_pylist(flat, schema=schema)
    buffer = io.BytesIO()
    pq.write_table(table, buffer)
    return buffer.getvalue()
