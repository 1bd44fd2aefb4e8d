"""One checkpoint's agent, loaded for judging: networks, normaliser and content hash.

:func:`deterministic_policy` is how every simulating judge acts: the action mean on
observations normalised with the checkpoint's own statistics, as the policy saw them in
training.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.errors import InputError
from engine.rl.checkpoint import load_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.inference import NumpyAgent
from engine.rl.judge_cache import file_digest
from engine.rl.networks import Agent
from engine.rl.normalize import ObsNormalizer


@dataclass(frozen=True)
class TrainedAgent:
    """The networks and normaliser of one checkpoint.

    Attributes:
        config: the run's configuration.
        agent: actor, critics and z_phi, in eval mode.
        obs_norm: the observation normaliser at that checkpoint.
        timesteps: env steps trained.
        digest: SHA-256 of the checkpoint file, the key of the judges' caches.
    """

    config: TrainConfig
    agent: Agent
    obs_norm: ObsNormalizer
    timesteps: int
    digest: str = ""


def load_agent(path: Path) -> TrainedAgent:
    """Rebuild the agent of a checkpoint file.

    Raises:
        InputError: the file is not an ACV checkpoint or its networks do not fit its config.
    """
    state = load_checkpoint(path)
    try:
        cfg = TrainConfig.from_json(state["config"])
        agent = Agent(
            int(state["obs_dim"]),
            int(state["act_dim"]),
            cfg.hidden,
            cfg.algo,
            cfg.z_max,
            cfg.z_init,
        )
        agent.load_state_dict(state["agent"])
        obs_norm = ObsNormalizer((int(state["obs_dim"]),), enabled=cfg.norm_obs)
        obs_norm.load_state_dict(state["obs_norm"])
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{path} is a damaged checkpoint ({type(exc).__name__}: {exc})") from exc
    return TrainedAgent(cfg, agent.eval(), obs_norm, int(state["timesteps"]), file_digest(path))


def deterministic_policy(trained: TrainedAgent) -> Callable[[np.ndarray], np.ndarray]:
    """The checkpoint's policy without exploration noise: observation -> action mean (to be
    clipped by the env's action space, as training does)."""
    net = NumpyAgent(trained.agent)

    def act(obs: np.ndarray) -> np.ndarray:
        x = trained.obs_norm(np.asarray(obs, dtype=np.float64)[None])
        action: np.ndarray = net.mean(x, net.z(x))[0]
        return action

    return act
