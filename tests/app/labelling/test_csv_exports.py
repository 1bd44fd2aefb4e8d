"""Every CSV the app serves is written by one writer that neutralises spreadsheet formulas
(issue 24, F3), on SQLite and PostgreSQL."""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path
from urllib.parse import urlencode

import pytest
from fastapi.testclient import TestClient

from app.core.csv_export import csv_text, safe_cell
from app.http.ratelimit import LoginLimiter
from tests.support.crowd import configure, joined_player, visit
from tests.support.web import ADMIN

APP = Path(__file__).resolve().parents[3] / "app"

#: Every operation answering ``text/csv``; a new one must be added here and to a test below.
CSV_ROUTES = {
    "/api/evaluations/{evaluation_id}/answers.csv",
    "/api/experiments/{experiment_id}/verdict.csv",
    "/api/runs/{run_id}/conformance.csv",
    "/api/studies/{study_id}/export/labels.{fmt}",
    "/api/studies/{study_id}/labels.csv",
    "/api/surveys/{survey_id}/answers.csv",
}

FORMULAS = ["=2+3", "@SUM(1+1)", '=HYPERLINK("http://x.example","a")', "+1", "-1+2"]


@pytest.mark.parametrize("cell", [*FORMULAS, "\tx", "\rx"])
def test_formula_cells_get_a_leading_quote(cell: str) -> None:
    assert safe_cell(cell) == "'" + cell
    assert next(csv.reader(io.StringIO(csv_text(["c"], [[cell]])), strict=True)) == ["c"]


@pytest.mark.parametrize("value", ["abc", "a=b", "", None, -0.5, -3, True])
def test_plain_cells_and_numbers_are_kept(value: object) -> None:
    assert safe_cell(value) == value


def test_the_openapi_document_lists_no_other_csv(client: TestClient) -> None:
    served = {
        path
        for path, ops in client.app.openapi()["paths"].items()
        for op in ops.values()
        if "text/csv" in op.get("responses", {}).get("200", {}).get("content", {})
    }
    assert served == CSV_ROUTES


def test_no_module_but_the_one_writer_writes_csv() -> None:
    writers = [
        str(p.relative_to(APP))
        for p in APP.rglob("*.py")
        if re.search(r"\bcsv\.(writer|DictWriter)\b", p.read_text())
    ]
    assert writers == ["core/csv_export.py"]


@pytest.mark.parametrize("external_id", FORMULAS)
def test_formula_external_ids_are_neutralised_in_the_label_export(
    client: TestClient, make_study, external_id: str
) -> None:
    client.app.state.join_limiter = LoginLimiter(30)
    study = make_study()
    link = configure(client, study["id"], enabled=True, max_participants=50)
    browser, response = visit(client, link, "?" + urlencode({"PROLIFIC_PID": external_id}))
    player = joined_player(client, browser, response)
    match = player.next_match()
    assert match is not None
    assert player.label(match["match_id"], match["a"]["candidate_id"]).status_code == 201
    export = client.get(f"/api/studies/{study['id']}/export/labels.csv", headers=ADMIN)
    assert export.status_code == 200
    row = next(csv.DictReader(io.StringIO(export.text)))
    assert row["external_id"] == "'" + external_id
    plain = client.get(f"/api/studies/{study['id']}/labels.csv", headers=ADMIN)
    assert all(not _runs_as_formula(c) for r in csv.reader(io.StringIO(plain.text)) for c in r)


def _runs_as_formula(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return cell.startswith(("=", "+", "-", "@", "\t", "\r"))
    return False
