"""An evaluation's answers for reuse (issue 41 §2: "exported with the labels ..., with the
stimulus kind"), on both databases: ``answers.jsonl`` and ``answers.parquet`` hold
``answers.csv``'s columns, one row per kept answer, each with what was shown (``stimulus``,
``reminder``); a withdrawn evaluator's answers are left out; researcher only.

The evaluation is a bare one (its rows written directly, nothing rendered), answered through
the evaluators' API.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterator
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from fastapi.testclient import TestClient

from app.evaluations.results import EXPORT_COLUMNS
from tests.support.evaluations import bare_evaluation
from tests.support.runs import TINY, create_run, run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN, logged_in


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def run_id(client: TestClient) -> int:
    """A run (never trained: the worker is off) for the bare evaluations' slots."""
    study = new_study(client, n_candidates=3, seed=6)
    return create_run(
        client, study_id=study["id"], teacher="good", algo="bipars-em", timesteps=256, **TINY
    )


def _bearers(
    client: TestClient, evaluation_id: int, count: int
) -> list[tuple[int, dict[str, str]]]:
    """``count`` new evaluators: each one's id and bearer header."""
    made = client.post(
        f"/api/evaluations/{evaluation_id}/evaluators", json={"count": count}, headers=ADMIN
    )
    assert made.status_code == 201, made.text
    return [
        (p["id"], {"Authorization": f"Bearer {p['invite_url'].rsplit('/', 1)[1]}"})
        for p in made.json()
    ]


def _answer(client: TestClient, who: dict[str, str], choice: str, stimulus: str) -> None:
    key = client.get("/api/evaluators/me/pairs/next", headers=who).json()["key"]
    body = {"choice": choice, "stimulus": stimulus}
    response = client.post(f"/api/evaluators/me/pairs/{key}", json=body, headers=who)
    assert response.status_code == 200, response.text


@pytest.fixture(scope="module")
def answered(client: TestClient, run_id: int) -> dict[str, Any]:
    """A bare evaluation (2 pairs each): the keeper answers both pairs, one as a clip and one
    as a still; the leaver answers one and withdraws."""
    evaluation_id = bare_evaluation(client, run_id=run_id)
    (keeper_id, keeper), (_, leaver) = _bearers(client, evaluation_id, 2)
    _answer(client, keeper, "left", "clip")
    _answer(client, keeper, "tie", "still")
    _answer(client, leaver, "right", "clip")
    left = client.post("/api/evaluators/me/withdraw", json={"withdraw": True}, headers=leaver)
    assert left.status_code == 200, left.text
    return {"id": evaluation_id, "keeper": keeper_id}


def _get(client: TestClient, evaluation_id: int, fmt: str) -> Any:
    response = client.get(f"/api/evaluations/{evaluation_id}/answers.{fmt}", headers=ADMIN)
    assert response.status_code == 200, response.text
    disposition = response.headers["content-disposition"]
    assert f'filename="evaluation-{evaluation_id}-answers.{fmt}"' in disposition
    return response


def test_jsonl_has_the_csv_columns_the_stimulus_kind_and_only_kept_answers(
    client, answered
) -> None:
    response = _get(client, answered["id"], "jsonl")
    assert response.headers["content-type"].startswith("application/x-ndjson")
    rows = [json.loads(line) for line in response.text.splitlines()]
    assert [list(r) for r in rows] == [list(EXPORT_COLUMNS)] * 2
    assert {r["evaluator_id"] for r in rows} == {answered["keeper"]}  # the leaver's: left out
    assert [r["stimulus"] for r in rows] == ["clip", "still"]
    assert [r["reminder"] for r in rows] == [False, False] and [r["tie"] for r in rows] == [
        False,
        True,
    ]
    assert [r["position"] for r in rows] == [0, 1]
    assert all(r["answered_at"].endswith("+00:00") for r in rows)
    table = csv.DictReader(io.StringIO(_get(client, answered["id"], "csv").text))
    assert table.fieldnames == list(EXPORT_COLUMNS)
    in_csv = list(table)
    assert [(r["slot_a"], r["slot_b"], r["stimulus"]) for r in in_csv] == [
        (str(r["slot_a"]), str(r["slot_b"]), r["stimulus"]) for r in rows
    ]


def test_parquet_is_typed_and_holds_the_same_rows(client, answered) -> None:
    response = _get(client, answered["id"], "parquet")
    assert response.headers["content-type"].startswith("application/vnd.apache.parquet")
    table = pq.read_table(io.BytesIO(response.content))
    assert table.column_names == list(EXPORT_COLUMNS) and table.num_rows == 2
    assert table.schema.field("stimulus").type == pa.string()
    assert table.schema.field("tie").type == pa.bool_()
    assert table.schema.field("answered_at").type == pa.timestamp("us", tz="UTC")
    rows = table.to_pylist()
    jsonl = [json.loads(line) for line in _get(client, answered["id"], "jsonl").text.splitlines()]
    for row, same in zip(rows, jsonl, strict=True):
        assert row["answered_at"].isoformat() == same["answered_at"]
        assert {k: v for k, v in row.items() if k != "answered_at"} == {
            k: v for k, v in same.items() if k != "answered_at"
        }


def test_an_unanswered_evaluation_exports_no_rows_with_the_same_columns(client, run_id) -> None:
    evaluation_id = bare_evaluation(client, run_id=run_id)
    assert _get(client, evaluation_id, "jsonl").text == ""
    table = pq.read_table(io.BytesIO(_get(client, evaluation_id, "parquet").content))
    assert table.column_names == list(EXPORT_COLUMNS) and table.num_rows == 0


def test_the_exports_are_the_researchers_and_name_a_real_evaluation(client, answered) -> None:
    for fmt in ("jsonl", "parquet"):
        path = f"/api/evaluations/{answered['id']}/answers.{fmt}"
        assert client.get(path).status_code == 401
        assert (
            client.get(f"/api/evaluations/999999/answers.{fmt}", headers=ADMIN).status_code == 404
        )
        assert client.get(f"/api/evaluations/x/answers.{fmt}", headers=ADMIN).status_code == 422
    assert (
        client.get(f"/api/evaluations/{answered['id']}/answers.xml", headers=ADMIN).status_code
        == 404
    )


def test_the_evaluation_page_links_the_exports(client, answered) -> None:
    html = logged_in(client).get(f"/evaluations/{answered['id']}").text
    for fmt in ("csv", "jsonl", "parquet"):
        assert f'href="/api/evaluations/{answered["id"]}/answers.{fmt}"' in html
