"""What a run trains, as the services take it: a typed spec with one advice source.

A request names its advice with four optional fields (``participant_id``,
``participant_ids``, ``all_participants``, ``teacher``), and a pool's weighting with
``pool_weighting``; :meth:`RunSpec.from_request` turns them into one :data:`AdviceSource` (or
refuses two at once), and :meth:`RunSpec.to_request` gives the flat form back (an experiment
stores it).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any, Literal, cast, get_args

from engine.errors import InputError

#: The request fields that name the advice source.
ADVICE_FIELDS = ("participant_id", "participant_ids", "all_participants", "teacher")
#: How a pool's trees are averaged: the plain mean, or weighted by each participant's
#: reliability (:func:`app.runs.pools.reliability_weights`).
PoolWeighting = Literal["mean", "reliability"]
POOL_WEIGHTINGS: tuple[str, ...] = get_args(PoolWeighting)
#: Run options that only shape the advice: a no-advice baseline trains without them.
ADVICE_OPTIONS = ("advice_mode", "advice_scale")
_IDENTITY = ("study_id", "algo", "timesteps", "seed", "n_envs", "pool_weighting", *ADVICE_FIELDS)


@dataclass(frozen=True)
class ParticipantAdvice:
    """One finished participant's Human Preference Tree."""

    participant_id: int


@dataclass(frozen=True)
class PooledAdvice:
    """Several finished participants' trees pooled; ``participant_ids`` None: every
    finished participant of the study (not excluded). ``weighting``: how their trees'
    F are averaged."""

    participant_ids: tuple[int, ...] | None = None
    weighting: PoolWeighting = "mean"


@dataclass(frozen=True)
class TeacherAdvice:
    """A simulated teacher's tree over the study's bracket."""

    teacher: str


#: Where a run's advice comes from; None: no advice (``ppo`` only).
AdviceSource = ParticipantAdvice | PooledAdvice | TeacherAdvice | None


@dataclass(frozen=True)
class RunSpec:
    """A run to create: its study, advice, algorithm, budget, seed and further
    :class:`~engine.rl.config.TrainConfig` fields (``options``; absent: the defaults)."""

    study_id: int
    timesteps: int
    advice: AdviceSource = None
    algo: str = "bipars-em"
    seed: int = 0
    n_envs: int = 4
    options: Mapping[str, int | float | str] = field(default_factory=dict)

    @classmethod
    def from_request(cls, request: Mapping[str, Any]) -> RunSpec:
        """The spec of a flat request (``/api/runs``'s fields; None values left out).

        Raises:
            InputError: more than one advice source.
        """
        given = {k: v for k, v in request.items() if v is not None}
        return cls(
            study_id=given["study_id"],
            timesteps=given["timesteps"],
            advice=advice_source(given),
            algo=str(given.get("algo", "bipars-em")),
            seed=given.get("seed", 0),
            n_envs=given.get("n_envs", 4),
            options={k: v for k, v in given.items() if k not in _IDENTITY},
        )

    def to_request(self) -> dict[str, Any]:
        """The flat request, less ``seed`` (an experiment's runs differ by seed only)."""
        return {
            "study_id": self.study_id,
            **advice_fields(self.advice),
            "algo": self.algo,
            "timesteps": self.timesteps,
            "n_envs": self.n_envs,
            **self.options,
        }

    def baseline(self, seed: int) -> RunSpec:
        """The matched no-advice ``ppo`` run at ``seed``: the same advice named (so that its
        checkpoints are judged against it), without the options that only shape advice."""
        options = {k: v for k, v in self.options.items() if k not in ADVICE_OPTIONS}
        return replace(self, algo="ppo", seed=seed, options=options)


def advice_source(fields: Mapping[str, Any]) -> AdviceSource:
    """The one advice source that the request ``fields`` name.

    Raises:
        InputError: more than one, or a ``pool_weighting`` other than the mean without a pool.
    """
    pooled = fields.get("participant_ids") is not None or bool(fields.get("all_participants"))
    weighting = _weighting(fields.get("pool_weighting"), pooled=pooled)
    named = (fields.get("participant_id") is not None, fields.get("teacher") is not None, pooled)
    if sum(named) > 1:
        raise InputError(
            "give one advice source: participant_id, participant_ids (or all_participants) "
            "or teacher, not both"
        )
    if fields.get("participant_ids") is not None and fields.get("all_participants"):
        raise InputError("give participant_ids or all_participants, not both")
    if fields.get("participant_id") is not None:
        return ParticipantAdvice(fields["participant_id"])
    if fields.get("teacher") is not None:
        return TeacherAdvice(str(fields["teacher"]))
    ids = fields.get("participant_ids")
    return PooledAdvice(None if ids is None else tuple(ids), weighting) if pooled else None


def _weighting(given: Any, *, pooled: bool) -> PoolWeighting:
    """``pool_weighting`` checked: one of :data:`POOL_WEIGHTINGS`, and not the mean only
    for pooled advice."""
    if given is None:
        return "mean"
    if given not in POOL_WEIGHTINGS:
        raise InputError(
            f"unknown pool_weighting {given!r}: expected one of {', '.join(POOL_WEIGHTINGS)}"
        )
    if given != "mean" and not pooled:
        raise InputError(
            f"pool_weighting {given!r} weights a pool: give participant_ids or all_participants"
        )
    return cast(PoolWeighting, given)


def advice_fields(source: AdviceSource) -> dict[str, Any]:
    """The request fields naming ``source`` (none for no advice)."""
    match source:
        case ParticipantAdvice(participant_id):
            return {"participant_id": participant_id}
        case PooledAdvice(ids, weighting):
            chosen = {"all_participants": True} if ids is None else {"participant_ids": list(ids)}
            # the mean is left out: requests stored before weighting existed stay the same
            return chosen | ({} if weighting == "mean" else {"pool_weighting": weighting})
        case TeacherAdvice(teacher):
            return {"teacher": teacher}
    return {}
