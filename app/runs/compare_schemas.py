"""Response bodies of the comparison endpoints of ``/api/runs`` (conformance, curves, the
checkpoint report), converted once from :class:`engine.conformance.Conformance` and
:class:`app.runs.comparison.CheckpointView`."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from app.runs.comparison import CheckpointView, highlights, score_column, verdict
from engine.conformance import Conformance, Contested, Rejection
from engine.judges import LEGACY_JUDGES
from engine.records import CandidateRow

#: An ``acv.tree/1`` document (see ``engine.treefile``), passed on as stored.
TreeJson = dict[str, Any]


class MetricsRowOut(BaseModel):
    """One update's metrics row (``metrics.jsonl``): timesteps, update, returns, z, losses...;
    which further scalars appear depends on the algorithm, so they pass through."""

    model_config = ConfigDict(extra="allow")

    timesteps: int
    update: int


@dataclass(frozen=True)
class RejectionOut(Rejection):
    """A human match the agent decided the other way."""

    contested: Annotated[
        bool, Field(description="The human's winner has the lower environment reward.")
    ] = field()  # required here, as the API always sends it


@dataclass(frozen=True)
class ContestedOut(Contested):
    """Agreement over the human's contested matches (where the advice goes against R)."""


@dataclass(frozen=True)
class ConformanceOut(Conformance):
    """The metrics of ``acv compare --json``."""

    rejected: list[RejectionOut]  # type: ignore[assignment]  # a list of the subclass
    contested: ContestedOut
    reference_agreement: Annotated[
        float,
        Field(description="The match agreement of a judge by the environment's reward R alone."),
    ]

    @classmethod
    def of(cls, m: Conformance) -> ConformanceOut:
        return TypeAdapter(cls).validate_python(asdict(m))


@dataclass(frozen=True)
class CurvePointOut(ConformanceOut):
    """The conformance at one checkpoint."""

    checkpoint: int

    @classmethod
    def at(cls, step: int, m: Conformance) -> CurvePointOut:
        return TypeAdapter(cls).validate_python({**asdict(m), "checkpoint": step})


class JudgeOut(BaseModel):
    """One judge's agreement with the advice, for the side-by-side table."""

    judge: str
    n_matches: int
    n_agree: int
    match_agreement: float
    contested: ContestedOut


@dataclass(frozen=True)
class CandidateRowOut(CandidateRow):
    """One candidate: R, F, z, z F, the judges' scores, V (the engine's record, and the
    score of the judge asked for)."""

    env_return: Annotated[
        float | None,
        Field(description="The return judge's score (none in reports from before that judge)."),
    ] = None
    score: Annotated[float, Field(description="The selected judge's score of this candidate.")] = (
        field(kw_only=True)
    )


class HighlightsOut(BaseModel):
    """States to mark: in the human tree the losers of overturned matches, in the agent tree
    the human's winners the agent ruled against."""

    human: list[int]
    agent: list[int]


class AdvisorOut(BaseModel):
    """Pooled advice: one pooled participant's tree judged by the agent's tree."""

    participant_id: int
    conformance: ConformanceOut


class AdvisorsOut(BaseModel):
    """Pooled advice at one checkpoint and judge: the agent against each participant's tree,
    and against the pooled verdict (the run's advice tree)."""

    checkpoint: int
    judge: str
    advisors: list[AdvisorOut]
    pooled: ConformanceOut

    @classmethod
    def of(cls, view: CheckpointView, judge: str) -> AdvisorsOut:
        judge = LEGACY_JUDGES.get(judge, judge)
        return cls(
            checkpoint=view.step,
            judge=judge,
            advisors=_advisors(view, judge),
            pooled=ConformanceOut.of(view.of(judge)),
        )


def _advisors(view: CheckpointView, judge: str) -> list[AdvisorOut]:
    return [
        AdvisorOut(participant_id=pid, conformance=ConformanceOut.of(m))
        for pid, m in view.advisors_of(judge)
    ]


class CheckpointReportOut(BaseModel):
    """What the compare page shows of one checkpoint and judge, ready to render."""

    checkpoint: int
    judge: str
    verdict: str
    conformance: ConformanceOut
    highlights: HighlightsOut
    judges: list[JudgeOut]
    candidates: list[CandidateRowOut]
    advisors: list[AdvisorOut] | None = Field(
        None, description="Pooled advice: the agent against each pooled participant's tree."
    )

    @classmethod
    def of(cls, view: CheckpointView, judge: str, whose: str) -> CheckpointReportOut:
        judge = LEGACY_JUDGES.get(judge, judge)
        m = view.of(judge)
        human, agent = highlights(m)
        return cls(
            checkpoint=view.step,
            judge=judge,
            verdict=verdict(view, judge, whose),
            conformance=ConformanceOut.of(m),
            highlights=HighlightsOut(human=sorted(human), agent=sorted(agent)),
            judges=[
                JudgeOut(
                    judge=j,
                    n_matches=c.n_matches,
                    n_agree=c.n_agree,
                    match_agreement=c.match_agreement,
                    contested=ContestedOut(**asdict(c.contested)),
                )
                for j, c in view.conformance.items()
            ],
            candidates=[
                CandidateRowOut(**asdict(row), score=_score(asdict(row), judge))
                for row in view.candidates
            ],
            advisors=_advisors(view, judge) if view.advisors else None,
        )


def _score(row: dict[str, Any], judge: str) -> float:
    """The judge's score of a candidate: its column (:func:`score_column`)."""
    return float(row[score_column(judge)])
