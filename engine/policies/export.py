"""An ACV checkpoint's deterministic policy as ONNX: ACV's own runs on the import path.

The graph computes what :func:`engine.rl.trained.deterministic_policy` computes after the
normaliser: the actor's mean on the normalised observation, with BiPaRS-EM's z_phi(s) as its
last input (:mod:`engine.policies.onnx_build`). The normaliser travels beside it as an
:class:`~engine.policies.normalisation.ObsNormalisation` (float64 outside the graph, as in
training; that module says why). Exported, checked and judged in a child, a checkpoint's
``behaviour`` and ``return`` measures equal the native path's to about 1e-7 relative: the same
float32 network, summed in another order by onnxruntime's kernels than by numpy's BLAS
(tests/engine/policies/test_onnx_roundtrip.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from engine import __version__
from engine.policies.normalisation import ObsNormalisation
from engine.policies.onnx_build import Layer, ZBranch, mlp_onnx
from engine.rl.normalize import OBS_EPSILON, ObsNormalizer
from engine.rl.trained import TrainedAgent

#: ``metadata_props`` keys of the declared training settings an export carries.
ALGORITHM_KEY = "algorithm"
TIMESTEPS_KEY = "timesteps"
SEED_KEY = "seed"


@dataclass(frozen=True, eq=False)
class ExportedPolicy:
    """What an import needs: the ONNX file and the observation normalisation.

    Attributes:
        onnx: the serialised model.
        normalisation: the checkpoint's normaliser; None when the run did not normalise.
    """

    onnx: bytes
    normalisation: ObsNormalisation | None


def export_agent(trained: TrainedAgent) -> ExportedPolicy:
    """The checkpoint's deterministic policy (see the module docstring).

    Args:
        trained: a checkpoint loaded with :func:`engine.rl.trained.load_agent`.
    """
    cfg = trained.config
    actor = trained.agent.actor
    z_branch = None
    if actor.z_input:  # bipars-em: pi(a | s, z_phi(s))
        z_net = trained.agent.z_net
        if z_net is None:  # Agent builds z_phi for every bipars-* run
            raise AssertionError("a z-input actor without z_phi")
        z_branch = ZBranch(_linear_layers(z_net.net), z_net.z_max)
    metadata = {
        ALGORITHM_KEY: f"acv {cfg.algo}",
        TIMESTEPS_KEY: str(trained.timesteps),
        SEED_KEY: str(cfg.seed),
        "producer": f"acv {__version__}",
        "checkpoint_sha256": trained.digest,
    }
    data = mlp_onnx(
        _linear_layers(actor.mean), env_id=cfg.env_id, z_branch=z_branch, metadata=metadata
    )
    return ExportedPolicy(data, normalisation_of(trained.obs_norm))


def normalisation_of(norm: ObsNormalizer) -> ObsNormalisation | None:
    """ACV's running normaliser as the file form; None when it is disabled."""
    if not norm.enabled:
        return None
    return ObsNormalisation(
        np.array(norm.rms.mean, dtype=np.float64),
        np.array(norm.rms.var, dtype=np.float64),
        float(norm.clip),
        OBS_EPSILON,
    )


def _linear_layers(seq: nn.Sequential) -> list[Layer]:
    """Copies of the ``(weight, bias)`` of each Linear of an :func:`engine.rl.networks.mlp`."""
    with torch.no_grad():
        return [
            (m.weight.detach().numpy().copy(), m.bias.detach().numpy().copy())
            for m in seq
            if isinstance(m, nn.Linear)
        ]
