"""The crowd part of a study's page (issue 14): the open-link form (:func:`crowd_options`;
posted to :mod:`app.studies.pages`), quality flags and the agreement heat map
(:func:`crowd_context`, rendered by ``templates/study_crowd.html``)."""

from __future__ import annotations

from typing import Any

from fastapi import Request
from sqlalchemy.orm import Session

from app.labelling import consensus, quality, study_link
from app.recruiting import service as recruiting
from app.recruiting.kinds import open_url
from app.recruiting.pages import link_form, validated, whole
from app.studies import crowd, gold
from app.studies.crowd_schemas import CrowdIn
from engine.errors import InputError


def _heat(value: float | None) -> str:
    """A heat-map cell's class: ``heat-0`` .. ``heat-10`` by agreement, ``heat-none``."""
    return "heat-none" if value is None else f"heat-{round(value * 10)}"


def heat_map(agreement: consensus.StudyAgreement) -> list[dict[str, Any]]:
    """Rows of the participants x participants table: each cell's text, class and title."""
    by_pair = {(p.a, p.b): p for p in agreement.pairs}
    rows = []
    for i in agreement.participants:
        cells = []
        for j in agreement.participants:
            pair = by_pair.get((min(i, j), max(i, j)))
            if i == j or pair is None:
                cells.append({"text": "—", "cls": "heat-self", "title": "the same participant"})
                continue
            text = "no shared pair" if pair.agreement is None else f"{pair.agreement:.0%}"
            cells.append(
                {
                    "text": text,
                    "cls": _heat(pair.agreement),
                    "title": f"#{i} and #{j}: {pair.shared} shared pairs",
                }
            )
        rows.append({"id": i, "cells": cells})
    return rows


def crowd_context(request: Request, session: Session, study_id: int) -> dict[str, Any]:
    """What ``study_crowd.html`` shows: settings and link, quality, agreement."""
    row = recruiting.settings(session, study_link.LINK, study_id)
    agreement = consensus.study_agreement(session, study_id=study_id)
    teachers: dict[int, dict[str, float | None]] = {}
    for t in agreement.teachers:
        teachers.setdefault(t.participant_id, {})[t.teacher] = t.agreement
    return {
        "crowd": row,
        "crowd_defaults": crowd.CrowdOptions(),
        "open_url": None if row is None else open_url(study_link.LINK, request.base_url, row.slug),
        "quality": quality.quality(session, study_id=study_id),
        "agreement": agreement,
        "heat_rows": heat_map(agreement),
        "teacher_names": consensus.COMPARED_TEACHERS,
        "teacher_agreement": teachers,
        "gold_items": gold.list_items(session, study_id=study_id),
    }


def crowd_options(fields: dict[str, str]) -> crowd.CrowdOptions:
    """The form's fields, validated like ``PUT /api/studies/{id}/crowd``."""
    body = validated(
        CrowdIn,
        link_form(fields)
        | {
            "consistency_check": fields.get("consistency_check") == "on",
            "speed_threshold_ms": whole(fields, "speed_threshold_ms"),
            "gold_gate": _share(fields, "gold_gate"),
            "gate_excludes": fields.get("gate_excludes") == "on",
            "gate_code": fields.get("gate_code", "").strip() or None,
            "time_limit_min": _optional_whole(fields, "time_limit_min"),
        },
    )
    return body.options(crowd.CrowdOptions)


def _optional_whole(fields: dict[str, str], name: str) -> int | None:
    """An optional whole-number field: ``None`` when left empty."""
    return whole(fields, name) if fields.get(name, "").strip() else None


def _share(fields: dict[str, str], name: str) -> float | None:
    """An optional number field: ``None`` when left empty."""
    text = fields.get(name, "").strip()
    try:
        return float(text) if text else None
    except ValueError:
        raise InputError(f"{name} must be a number from 0 to 1") from None
