"""An HTML form's whole numbers: one rule (:func:`app.core.json_types.form_int`) for every
form, as strict as the JSON body's where it can be; Python's ``int()`` read ``1_0`` as 10, and
a 20-digit id overflowed SQLite (a 500)."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient
from pydantic import ValidationError

from app.core.json_types import form_int, from_form
from app.core.limits import INT64_MAX
from app.studies.schemas import StudyCreate
from tests.support.web import ADMIN, csrf_token, logged_in


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("12", 12),
        (" 12 ", 12),  # a person's stray space
        ("-3", -3),
        ("0", 0),
        (str(INT64_MAX), INT64_MAX),
        (str(INT64_MAX + 1), None),
        ("9" * 20, None),
        ("1_0", None),
        ("16.0", None),
        ("+1", None),
        ("1e3", None),
        ("0x10", None),
        ("", None),
        ("١٢", None),  # Arabic-Indic digits, which int() reads as 12
    ],
)
def test_form_int_reads_decimal_digits_within_64_bits(text: str, value: int | None) -> None:
    assert form_int(text) == value


@pytest.mark.parametrize("bad", ["1_6", "16.0", "+16", "9" * 20])
def test_a_form_body_refuses_what_a_json_body_would(bad: str) -> None:
    with pytest.raises(ValidationError) as refused:
        from_form(StudyCreate, {"name": "x", "n_candidates": bad})
    (error,) = refused.value.errors()
    assert error["loc"] == ("n_candidates",) and "decimal digits" in error["msg"]
    assert from_form(StudyCreate, {"name": "x", "n_candidates": " 16 "}).n_candidates == 16


def test_the_invite_form_refuses_a_lax_count(client: TestClient, study: dict[str, Any]) -> None:
    page = logged_in(client)
    before = client.get(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    for count in ("1_0", "2.0", "9" * 20):
        token = csrf_token(page, f"/studies/{study['id']}")
        answer = page.post(
            f"/studies/{study['id']}/participants", data={"csrf_token": token, "count": count}
        )
        assert answer.status_code == 422 and "whole number" in answer.text, count
    after = client.get(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    assert len(after) == len(before)
