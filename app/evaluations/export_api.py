"""``/api/evaluations/{id}/answers.jsonl`` and ``answers.parquet``: an evaluation's answers
for reuse (issue 41 §2, "exported with the labels ..., with the stimulus kind"), beside
``answers.csv`` (:mod:`app.evaluations.api`), with its columns
(:data:`app.evaluations.results.EXPORT_COLUMNS`: each answer's slots, runs, arms, sides, the
choice, the response time, and what was shown: ``stimulus``, ``still`` or ``clip``, and
``reminder``). Kept evaluators only: one who withdrew, ran out of time or was excluded is
left out (:func:`app.evaluations.results.kept_pairs`). Researcher only.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fastapi import APIRouter, Response

from app.evaluations import results
from app.evaluations import service as evaluations
from app.http.deps import DbId, ResearcherDep, SessionDep
from app.http.files import attachment

router = APIRouter(tags=["evaluations"])

Writer = Callable[[list[dict[str, Any]]], "bytes | str"]
#: Format -> (media type, writer).
FORMATS: dict[str, tuple[str, Writer]] = {
    "jsonl": ("application/x-ndjson", results.to_jsonl),
    "parquet": ("application/vnd.apache.parquet", results.to_parquet),
}


def _export(session: SessionDep, evaluation_id: int, fmt: str) -> Response:
    """The kept answers of ``evaluation_id`` in ``fmt``.

    Raises:
        NotFoundError: no such evaluation (404).
    """
    evaluations.get_evaluation(session, evaluation_id=evaluation_id)
    media_type, write = FORMATS[fmt]
    body = write(results.export_rows(session, evaluation_id=evaluation_id))
    return attachment(body, media_type, f"evaluation-{evaluation_id}-answers.{fmt}")


@router.get(
    "/evaluations/{evaluation_id}/answers.jsonl",
    response_class=Response,
    responses={200: {"content": {"application/x-ndjson": {}}}},
)
def answers_jsonl(evaluation_id: DbId, session: SessionDep, _: ResearcherDep) -> Response:
    """Every kept answer as JSON Lines, one object a pair, with ``answers.csv``'s columns
    (``answered_at`` in ISO 8601, UTC)."""
    return _export(session, evaluation_id, "jsonl")


@router.get(
    "/evaluations/{evaluation_id}/answers.parquet",
    response_class=Response,
    responses={200: {"content": {"application/vnd.apache.parquet": {}}}},
)
def answers_parquet(evaluation_id: DbId, session: SessionDep, _: ResearcherDep) -> Response:
    """Every kept answer as Parquet (``datasets.load_dataset("parquet", ...)`` reads it),
    with ``answers.csv``'s columns, typed."""
    return _export(session, evaluation_id, "parquet")
