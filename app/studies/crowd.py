"""Crowd recruiting of a study (issue 14): its open link's label-quality options.

Joining, resuming, consent and the completion code are :mod:`app.recruiting.service`,
written once for studies and surveys. The link as participants join it (its kind,
:data:`app.labelling.study_link.LINK`: a new participant gets their first round of matches
as they join) is the participant's journey, in :mod:`app.labelling.study_link`.
"""

from __future__ import annotations

from dataclasses import dataclass

from app.recruiting.links import (
    DEFAULT_EXTERNAL_PARAMS,
    MAX_PARTICIPANTS,
    LinkFullError,
    LinkOptions,
    is_full,
)
from engine.errors import InputError

__all__ = ["DEFAULT_EXTERNAL_PARAMS", "MAX_PARTICIPANTS", "StudyFullError", "is_full"]
DEFAULT_SPEED_THRESHOLD_MS = 800


class StudyFullError(LinkFullError):
    """The open link reached its largest number of participants."""


@dataclass(frozen=True)
class CrowdOptions(LinkOptions):
    """What the researcher sets for a study's open link and label-quality checks."""

    consistency_check: bool = False
    speed_threshold_ms: int = DEFAULT_SPEED_THRESHOLD_MS
    gold_gate: float | None = None
    gate_excludes: bool = False
    gate_code: str | None = None


def check_options(options: CrowdOptions) -> None:
    """Refuse label-quality options out of range (the open link's own are checked by
    :func:`app.recruiting.service.configure`).

    Raises:
        InputError: a speed threshold outside 0..600000 ms, or a gate outside [0, 1].
    """
    if not 0 <= options.speed_threshold_ms <= 600_000:
        raise InputError("speed_threshold_ms must be in 0..600000")
    if options.gold_gate is not None and not 0.0 <= options.gold_gate <= 1.0:
        raise InputError(f"gold_gate must be in [0, 1], got {options.gold_gate}")
