"""Policies from elsewhere (issue 44 §2): ``POST /api/experiments/external`` creates an
experiment whose runs are imported policies, and ``POST /api/experiments/{id}/agents``
imports one (multipart: the ONNX model, its optional observation normalisation ``.npz``, the
arm and the declared training settings). The policy is queued to be judged by a worker, as a
run trains (202); the experiment's verdict then reads it like any run.

Only ONNX is accepted (an SB3 ``.zip`` is refused with 415: ``acv agents import`` converts
it); every other refusal is a 4xx naming its rule, and stores nothing. The body may be larger
than the API's usual limit, up to :data:`MAX_UPLOAD_BYTES`, which
:class:`app.middleware.BodySizeLimit` reads from the operation's ``x-max-body-bytes`` and
enforces before the body is read (a declared length over it is refused unread).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from fastapi import APIRouter, File, Form, Request, UploadFile
from pydantic import BaseModel, ConfigDict, Field, StrictBool

from app.core.errors import ServiceError
from app.core.json_types import IntParam, JsonInt
from app.http.deps import DbId, ResearcherDep, SessionDep, SettingsDep
from app.http.errors import RESPONSES
from app.jobs.settings import JobSettings
from app.runs.agent_import import AgentUpload, import_agent
from app.runs.declared import MAX_ALGORITHM, MAX_SEED, MAX_STEPS, Declared
from app.runs.experiments import DEFAULT_SEEDS, MAX_SEEDS, MIN_SEEDS
from app.runs.experiments_api import ExperimentOut, experiment_out
from app.runs.external import ExternalSpec, create_external_experiment
from app.runs.schemas import PoolIds, RunOut
from app.runs.spec import PoolWeighting, advice_source
from engine.policies.normalisation import MAX_NPZ_BYTES
from engine.policies.onnx_check import OnnxLimits
from engine.teachers import Teacher

router = APIRouter(prefix="/experiments", tags=["experiments"])
#: The model file's cap: the gate's (:class:`engine.policies.onnx_check.OnnxLimits`).
MAX_MODEL_BYTES = OnnxLimits().max_bytes
#: A whole upload: the model, the normalisation and the form's fields.
MAX_UPLOAD_BYTES = MAX_MODEL_BYTES + MAX_NPZ_BYTES + 64 * 1024
Seed = Annotated[int, IntParam(ge=0, le=MAX_SEED)]
Steps = Annotated[int, IntParam(ge=1, le=MAX_STEPS)]


class TooLarge(ServiceError):
    """An uploaded file over its cap."""

    status_code = 413


class ExternalExperimentCreate(BaseModel):
    """An experiment whose runs are imported policies: its study (whose env they act in) and
    the advice the advised ones trained with (one source, as for a run), frozen now."""

    model_config = ConfigDict(extra="forbid")

    study_id: JsonInt = Field(ge=1, le=2**31 - 1)
    participant_id: JsonInt | None = Field(None, ge=1, le=2**31 - 1)
    participant_ids: PoolIds | None = None
    all_participants: StrictBool = False
    pool_weighting: PoolWeighting = "mean"
    teacher: Teacher | None = None
    seeds: JsonInt = Field(
        DEFAULT_SEEDS,
        ge=MIN_SEEDS,
        le=MAX_SEEDS,
        description="The most policies of the advised arm, and of the baseline arm.",
    )

    def spec(self) -> ExternalSpec:
        source = advice_source(self.model_dump(exclude={"study_id", "seeds"}))
        return ExternalSpec(study_id=self.study_id, advice=source, seeds_per_arm=self.seeds)


@router.post("/external", status_code=201)
def create_external(
    body: ExternalExperimentCreate, session: SessionDep, _: ResearcherDep
) -> ExperimentOut:
    """Create an external experiment: it trains nothing; import its policies with
    ``POST /api/experiments/{id}/agents``. Its ``spec.tree_sha256`` is the hash of its advice
    tree (canonical JSON), which advised policies declare."""
    experiment = create_external_experiment(session, spec=body.spec())
    return experiment_out(session, experiment)


@router.post(
    "/{experiment_id}/agents",
    status_code=202,
    responses={
        415: {
            **RESPONSES[422],
            "description": "Not ONNX (an SB3 zip: `acv agents import` converts it).",
        }
    },
    openapi_extra={"x-max-body-bytes": MAX_UPLOAD_BYTES},
)
def import_policy(
    experiment_id: DbId,
    request: Request,
    session: SessionDep,
    settings: SettingsDep,
    _: ResearcherDep,
    model: Annotated[
        UploadFile, File(description="The policy as ONNX: obs [N, obs_dim] -> action.")
    ],
    arm: Annotated[Literal["advised", "baseline", "pilot"], Form()],
    obs_norm: Annotated[
        UploadFile | None,
        File(description="Observation normalisation: .npz of mean, var, clip, epsilon."),
    ] = None,
    env_id: Annotated[
        str | None, Form(max_length=100, description="Without env_id in the model's metadata.")
    ] = None,
    seed: Annotated[Seed | None, Form(description="Declared (else the metadata's seed).")] = None,
    steps: Annotated[
        Steps | None, Form(description="Declared env steps (else the metadata's timesteps).")
    ] = None,
    algorithm: Annotated[
        str | None, Form(max_length=MAX_ALGORITHM, description="Declared (else the metadata's).")
    ] = None,
    tree_sha256: Annotated[
        str | None, Form(max_length=64, description="The advice tree's hash (advised only).")
    ] = None,
) -> RunOut:
    """Import a policy trained elsewhere into an external experiment; it is queued to be judged
    (``status``), then takes part in the verdict. Refused with a 4xx naming the rule: not ONNX,
    a corrupt model, a forbidden op, external data, wrong sizes, a missing or wrong env id, a
    file over its cap, a seed already imported in its arm."""
    upload = AgentUpload(
        onnx=_read(model, MAX_MODEL_BYTES, "model"),
        arm=arm,
        declared=Declared(algorithm, steps, seed, tree_sha256),
        env_id=env_id,
        obs_norm=None if obs_norm is None else _read(obs_norm, MAX_NPZ_BYTES, "obs_norm"),
    )
    run = import_agent(
        session, experiment_id=experiment_id, upload=upload, runs_root=_runs_root(request, settings)
    )
    return RunOut.of(run)


def _read(upload: UploadFile, cap: int, name: str) -> bytes:
    """An uploaded file's bytes, refused when over ``cap`` before it is read."""
    if upload.size is not None and upload.size > cap:
        raise TooLarge(f"the {name} file is {upload.size} bytes, over its limit of {cap} bytes")
    data = upload.file.read(cap + 1)
    if len(data) > cap:
        raise TooLarge(f"the {name} file is over its limit of {cap} bytes")
    return data


def _runs_root(request: Request, settings: SettingsDep) -> Path:
    jobs: JobSettings = getattr(request.app.state, "job_settings", None) or JobSettings()
    return jobs.runs_root(settings)
