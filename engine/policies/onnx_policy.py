"""A checked ONNX policy run by onnxruntime: ``obs -> action mean``, as the judges act.

:class:`OnnxPolicy` is the same callable that :func:`engine.rl.trained.deterministic_policy`
returns for an ACV checkpoint (one float64 observation in, the action mean out, clipped by the
judge to the action space), so the ``behaviour`` and ``return`` judges roll out an imported
policy with their own code. onnxruntime runs with one intra-op and one inter-op thread: the
judges already run one rollout per core, and one thread also makes the arithmetic the same
from run to run.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

import numpy as np
import onnxruntime as ort

from engine.errors import InputError
from engine.policies.normalisation import ObsNormalisation
from engine.policies.onnx_check import CheckedOnnx


@dataclass(frozen=True, eq=False)
class ImportedPolicy:
    """Everything that decides an imported policy's actions.

    Attributes:
        model: the checked ONNX model.
        normalisation: applied to observations before the model; None when it has none.
    """

    model: CheckedOnnx
    normalisation: ObsNormalisation | None = None

    def __post_init__(self) -> None:
        norm = self.normalisation
        if norm is not None and norm.mean.shape != (self.model.obs_dim,):
            raise InputError(
                f"the normalisation is for {norm.mean.shape[0]} observation entries, the model "
                f"reads {self.model.obs_dim}"
            )

    @property
    def env_id(self) -> str:
        """The env the policy acts in."""
        return self.model.env_id

    @property
    def digest(self) -> str:
        """The judges' cache key: SHA-256 of the ONNX file, and of the normalisation's values
        when there is one (it changes the actions as much as the weights do)."""
        if self.normalisation is None:
            return self.model.digest
        h = hashlib.sha256(self.model.data)
        h.update(b"\0obs-normalisation\0")
        h.update(self.normalisation.content())
        return h.hexdigest()


def session_options() -> ort.SessionOptions:
    """One thread for the graph's ops and one between them, no spinning, no log lines."""
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.log_severity_level = 4  # failures are raised as exceptions: no log lines too
    options.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return options


class OnnxPolicy:
    """An imported policy as ``obs -> action mean`` (see the module docstring).

    Args:
        policy: a model that passed :func:`engine.policies.onnx_check.check_onnx`, and its
            normalisation.

    Raises:
        InputError: onnxruntime cannot load the model.
    """

    def __init__(self, policy: ImportedPolicy):
        self.model = policy.model
        self.normalisation = policy.normalisation
        try:
            self.session: Any = ort.InferenceSession(
                self.model.data, session_options(), providers=["CPUExecutionProvider"]
            )
        except Exception as exc:  # onnxruntime's own exception types are not exported
            raise InputError(f"onnxruntime cannot load the model: {_first_line(exc)}") from exc

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The action mean for one observation, shape ``(act_dim,)``, float32."""
        action: np.ndarray = self.actions(np.asarray(obs, dtype=np.float64)[None])[0]
        return action

    def actions(self, obs: np.ndarray) -> np.ndarray:
        """Action means for a batch, shape ``(B, act_dim)``, float32.

        Args:
            obs: observations, shape ``(B, obs_dim)`` (float64 as the env gives them).

        Raises:
            InputError: the model fails at run time, or computes another shape or a value
                that is not finite.
        """
        x = (
            self.normalisation(obs)
            if self.normalisation is not None
            else np.asarray(obs, dtype=np.float32)
        )
        try:
            (out,) = self.session.run([self.model.output_name], {self.model.input_name: x})
        except Exception as exc:
            raise InputError(f"the policy failed to run: {_first_line(exc)}") from exc
        return _checked_actions(out, len(x), self.model.act_dim)


def _checked_actions(out: Any, rows: int, act_dim: int) -> np.ndarray:
    """The model's output when it is float32 ``(rows, act_dim)`` and finite."""
    if not isinstance(out, np.ndarray) or out.dtype != np.float32 or out.shape != (rows, act_dim):
        shown = getattr(out, "shape", type(out).__name__)
        raise InputError(f"the policy computed {shown}, not float32 ({rows}, {act_dim})")
    if not np.isfinite(out).all():
        raise InputError("the policy computed an action that is not finite (NaN or inf)")
    return out


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
