"""Request and response bodies of ``/api/runs`` (pydantic models, shown in ``/docs``)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictBool

from app.core.json_types import JsonFloat, JsonInt, UtcDatetime
from app.core.rows import from_row
from app.models import Run, RunStatus
from app.runs.experiments import (
    DEFAULT_PILOT_SEEDS,
    DEFAULT_SEEDS,
    MAX_PILOT_SEEDS,
    MAX_SEEDS,
    MIN_SEEDS,
    PILOT_SEED_BASE,
    ExperimentSpec,
)
from app.runs.imported_schemas import ImportedOut
from app.runs.pools import members, weighting_of, weights_of
from app.runs.service import MAX_TIMESTEPS, advice_label
from app.runs.spec import PoolWeighting, RunSpec
from app.studies.schemas import ProgressOut
from engine.rl.config import AdviceMode, Algo, TrainConfig
from engine.teachers import Teacher

#: engine.judges.JUDGES, and ``value``, the old name of ``shaped-value`` (still accepted).
Judge = Literal["return", "behaviour", "shaped", "shaping", "shaped-value", "value"]
DbInt = Annotated[JsonInt, Field(ge=1, le=2**31 - 1)]
#: Participants one pooled run may name.
MAX_POOL = 1000
#: A pool's participant ids: the schema documents the two or more that
#: :func:`app.runs.pools.pool_ids` enforces, with its message that names the count.
PoolIds = Annotated[list[DbInt], Field(max_length=MAX_POOL, json_schema_extra={"minItems": 2})]


class RunCreate(BaseModel):
    """A new training run. Advice: ``participant_id`` (a finished participant of the study),
    ``participant_ids`` (two or more of them, pooled: F is the mean of their trees' F),
    ``all_participants`` (every finished participant not excluded, pooled), ``teacher`` (a
    simulated teacher over the study's bracket) or none (``ppo`` only). A pool's mean is
    plain or weighted by each participant's reliability (``pool_weighting``)."""

    model_config = ConfigDict(extra="forbid")

    study_id: JsonInt = Field(ge=1, le=2**31 - 1)
    participant_id: JsonInt | None = Field(None, ge=1, le=2**31 - 1)
    participant_ids: PoolIds | None = Field(
        None,
        description="Pooled advice: two or more distinct finished participants of the study.",
    )
    all_participants: StrictBool = Field(
        False,
        description="Pooled advice: every finished participant of the study not excluded.",
    )
    pool_weighting: PoolWeighting = Field(
        "mean",
        description="Pooled advice: ``mean`` (every tree counts the same) or ``reliability`` "
        "(each tree weighted by its participant's reliability, from their known-answer "
        "checks; the run records each weight, and why it weighted a participant down).",
    )
    teacher: Teacher | None = None
    algo: Algo = Algo.BIPARS_EM
    timesteps: JsonInt = Field(ge=1, le=MAX_TIMESTEPS, description="Env steps over all envs.")
    seed: JsonInt = Field(0, ge=0, le=2**31 - 1)
    n_envs: JsonInt = Field(4, ge=1, le=64)
    num_steps: JsonInt | None = Field(
        None, ge=2, le=65_536, description="Steps per env per rollout (default 512)."
    )
    num_minibatches: JsonInt | None = Field(None, ge=1, le=4096)
    update_epochs: JsonInt | None = Field(None, ge=1, le=100)
    checkpoint_every: JsonInt | None = Field(
        None,
        ge=1,
        le=MAX_TIMESTEPS,
        description="Env steps between checkpoints (default: about 10 checkpoints).",
    )
    advice_scale: JsonFloat | None = Field(
        None,
        gt=0,
        le=100,
        allow_inf_nan=False,
        description="Multiplies F(s) before shaping (default 1); 10 lets the advice dominate R.",
    )
    advice_mode: AdviceMode | None = Field(
        None,
        description="How F is made from the advice tree; ``reward``: F is the env's "
        "step reward (the tree is still what the agent is compared with).",
    )

    def spec(self) -> RunSpec:
        """The run this request asks for, as the services take it."""
        return RunSpec.from_request(self.model_dump())


class RunCreated(BaseModel):
    id: int
    status: RunStatus


class PoolWeightOut(BaseModel):
    """A pooled participant's weight in a reliability-weighted pool."""

    participant_id: int
    weight: float = Field(description="Their reliability when the run was created, in [0, 1].")
    why: str | None = Field(
        description="Why the pool weighted them down (below its highest weight); else null."
    )


class RunOut(BaseModel):
    """A run: what it trains, where it stands, its latest metrics row, its error."""

    id: int
    study_id: int
    participant_id: int | None
    participant_ids: list[int] | None = Field(
        description="The pooled participants of a run on pooled advice (else null)."
    )
    pool_weighting: PoolWeighting | None = Field(
        description="How a run on pooled advice averages its trees (else null)."
    )
    pool_weights: list[PoolWeightOut] | None = Field(
        description="Each pooled participant's weight and why, for ``reliability`` "
        "weighting (else null)."
    )
    teacher: str | None
    advice: str
    algo: str
    timesteps: int
    seed: int
    n_envs: int
    config: dict[str, Any]
    status: RunStatus
    progress: ProgressOut
    metrics: dict[str, Any] | None
    error: str | None
    cancel_requested: bool
    executor: str | None
    created_at: UtcDatetime
    started_at: UtcDatetime | None
    finished_at: UtcDatetime | None
    imported: ImportedOut | None = Field(
        None,
        description="A policy trained elsewhere, imported into an external experiment and "
        "judged by ACV, which did not see it train (null for runs ACV trained).",
    )

    @classmethod
    def of(cls, run: Run) -> RunOut:
        imported = ImportedOut.of(run)
        # an imported policy's progress is its judging: done once its one checkpoint is stored
        total = run.timesteps if imported else _budget(TrainConfig.from_json(run.config))
        weights = weights_of(run)
        return from_row(
            cls,
            run,
            participant_ids=members(run),
            pool_weighting=weighting_of(run),
            pool_weights=None if weights is None else [PoolWeightOut(**vars(w)) for w in weights],
            advice=advice_label(run),
            progress=ProgressOut(done=run.progress, total=total),
            imported=imported,
        )


def _budget(config: TrainConfig) -> int:
    """The env steps a run trains: whole updates of ``n_envs x num_steps``."""
    return config.num_updates * config.batch_size


class CheckpointOut(BaseModel):
    """A checkpoint and the metrics row of the update that wrote it (when logged)."""

    checkpoint: int
    metrics: dict[str, Any] | None


class ExperimentCreate(RunCreate):
    """A run request (``/api/runs``'s body, whose ``seed`` is the first evaluation seed)
    trained on ``seeds`` seeds, with a matched ``ppo`` baseline on the same seeds and
    ``pilot_seeds`` pilot runs that pick the contested matches."""

    model_config = ConfigDict(extra="forbid")

    seeds: JsonInt = Field(DEFAULT_SEEDS, ge=MIN_SEEDS, le=MAX_SEEDS)
    pilot_seeds: JsonInt = Field(DEFAULT_PILOT_SEEDS, ge=1, le=MAX_PILOT_SEEDS)
    seed: JsonInt = Field(0, ge=0, lt=PILOT_SEED_BASE - MAX_SEEDS)

    def experiment_spec(self) -> ExperimentSpec:
        run = RunSpec.from_request(self.model_dump(exclude={"seeds", "pilot_seeds", "seed"}))
        return ExperimentSpec(
            run=run, seeds=self.seeds, first_seed=self.seed, pilot_seeds=self.pilot_seeds
        )
