"""Response bodies of imported policies: what a run that ACV judged but did not train says
about itself (``RunOut.imported``, ``ExperimentRunOut.imported``)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field

from app.models import ExperimentRole, Run
from app.runs.imported import imported_of

#: The words every page and answer puts beside declared training settings.
NOT_SEEN = "ACV did not see them train"


class DeclaredOut(BaseModel):
    """Training settings as declared with the upload or in the model's metadata."""

    algorithm: str
    steps: int
    seed: int
    tree_sha256: str | None = Field(description="The tree its advice wrapper used (advised only).")


class ImportedOut(BaseModel):
    """A policy trained elsewhere and imported: judged by ACV, never trained by it."""

    arm: ExperimentRole
    uploaded_as: str = Field(description="``onnx``, or ``sb3-zip`` converted by the CLI.")
    onnx_sha256: str = Field(description="The stored ONNX file's SHA-256 (its name).")
    obs_norm_sha256: str | None = Field(description="The observation normalisation's, if any.")
    env_id: str
    declared: DeclaredOut
    tree_matches: bool | None = Field(
        description="Whether the declared tree hash is the experiment's (null: none declared)."
    )
    metadata: dict[str, Any] = Field(description="The model's metadata_props (cut short).")
    sb3: dict[str, Any] | None = Field(description="An SB3 save's plain JSON fields, if any.")
    note: str = Field(NOT_SEEN, description="The declared settings are the trainer's word.")

    @classmethod
    def of(cls, run: Run) -> ImportedOut | None:
        """The run's import, or None for a run ACV trained."""
        info = imported_of(run)
        if info is None:
            return None
        return cls(
            arm=info["arm"],
            uploaded_as=info["uploaded_as"],
            onnx_sha256=info["onnx_sha256"],
            obs_norm_sha256=info.get("obs_norm_sha256"),
            env_id=info["env_id"],
            declared=DeclaredOut(**info["declared"]),
            tree_matches=info.get("tree_matches"),
            metadata=info.get("metadata") or {},
            sb3=info.get("sb3"),
            note=NOT_SEEN,
        )
