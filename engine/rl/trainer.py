"""One training run in memory: networks, optimisers, normalisers, envs, and one iteration.

An iteration collects a rollout, takes the PPO update on the shaped reward and, for BiPaRS,
the z_phi update on the true reward (Hu et al. 2020, Algorithm 1). The whole state round-trips
through :meth:`Trainer.state_dict`, so a resumed run continues exactly.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from typing import Any, cast

import numpy as np
import torch

from engine.gym_types import box
from engine.rl.bipars import em_update, mgl_update
from engine.rl.config import TrainConfig
from engine.rl.networks import Agent
from engine.rl.normalize import ObsNormalizer, RewardScaler
from engine.rl.optim import flat_adam
from engine.rl.ppo import make_batch, ppo_update
from engine.rl.rollout import Collector
from engine.rl.shaping import AdviceFn
from engine.rl.vecenv import make_vec_env, restore_vec, snapshot_vec


class Trainer:
    """PPO / PPO-shaped / BiPaRS-EM / BiPaRS-MGL learner for one :class:`TrainConfig`.

    Args:
        cfg: the run's configuration.
        advice: the advice reward F (required by the shaped algorithms, optional for ``ppo``
            where it is only logged).
        env_processes: 2 steps half of the envs in a helper process, at the same time as the
            other half (:func:`make_vec_env`); it changes speed, never numbers, so it is no
            part of the config.
    """

    def __init__(self, cfg: TrainConfig, advice: AdviceFn | None, env_processes: int = 1):
        self.cfg = cfg
        self.rng = np.random.default_rng(cfg.seed)
        self.envs = make_vec_env(
            cfg.env_id, cfg.n_envs, advice, cfg.advice_scale, cfg.advice_offset, env_processes
        )
        try:
            self._start(cfg)
        except BaseException:
            self.envs.close()  # never leave a helper process behind
            raise

    def _start(self, cfg: TrainConfig) -> None:
        first_obs, _ = self.envs.reset(seed=cfg.seed)
        obs_dim = box(self.envs.single_observation_space).shape[0]
        act_dim = box(self.envs.single_action_space).shape[0]
        with torch.random.fork_rng(devices=[]):  # seeded initialisation, global RNG untouched
            torch.manual_seed(cfg.seed)
            self.agent = Agent(obs_dim, act_dim, cfg.hidden, cfg.algo, cfg.z_max, cfg.z_init)
        self.optimizer = flat_adam(self.agent.policy_params(), cfg.learning_rate)
        self.z_optimizer = (
            flat_adam(list(self.agent.z_net.parameters()), cfg.z_learning_rate)
            if self.agent.z_net is not None
            else None
        )
        self.obs_norm = ObsNormalizer((obs_dim,), enabled=cfg.norm_obs)
        scaler = RewardScaler(cfg.n_envs, cfg.gamma, enabled=cfg.norm_reward)
        self.collector = Collector(
            self.envs,
            first_obs,
            self.agent,
            self.obs_norm,
            scaler,
            cfg.gamma,
            np.random.default_rng([cfg.seed, 1]),
        )
        self.update = 0
        self.timesteps = 0
        self.recent: deque[float] = deque(maxlen=100)

    @property
    def done(self) -> bool:
        """Whether all updates of the run have been taken."""
        return self.update >= self.cfg.num_updates

    def iterate(self) -> dict[str, Any]:
        """Collect one rollout and update; return the metrics row (without ``sps``)."""
        cfg = self.cfg
        if cfg.anneal_lr:
            self.optimizer.param_groups[0]["lr"] = cfg.learning_rate * (
                1.0 - self.update / cfg.num_updates
            )
        rollout, episodes, spread = self.collector.collect(cfg.num_steps)
        batch = make_batch(rollout, cfg)
        theta = {k: v.detach().clone() for k, v in self.agent.actor.named_parameters()}
        losses = ppo_update(self.agent, self.optimizer, batch, cfg, self.rng)
        z_optimizer = cast(torch.optim.Optimizer, self.z_optimizer)  # set for both bipars-*
        if cfg.algo == "bipars-em":
            losses |= em_update(self.agent, z_optimizer, batch, cfg)
        elif cfg.algo == "bipars-mgl":
            losses |= mgl_update(self.agent, z_optimizer, rollout, batch, cfg, theta)
        self.update += 1
        self.timesteps += cfg.batch_size
        self.recent.extend(episodes.true_returns)
        return {
            "timesteps": self.timesteps,
            "update": self.update,
            "episodic_return": _mean(episodes.true_returns),
            "shaped_return": _mean(episodes.shaped_returns),
            "episode_length": _mean(episodes.lengths),
            "episodes": len(episodes.lengths),
            "return_100": _mean(list(self.recent)),
            **spread,
            "learning_rate": self.optimizer.param_groups[0]["lr"],
            **losses,
            "time": time.time(),
            "episode_returns": episodes.true_returns,
            "episode_shaped_returns": episodes.shaped_returns,
        }

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to rebuild the networks and continue the run exactly."""
        return {
            "config": self.cfg.to_json(),
            "update": self.update,
            "timesteps": self.timesteps,
            "obs_dim": self.agent.critics.weights[0].shape[1],
            "act_dim": self.agent.actor.log_std.numel(),
            "agent": self.agent.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "z_optimizer": None if self.z_optimizer is None else self.z_optimizer.state_dict(),
            "obs_norm": self.obs_norm.state_dict(),
            "reward_scaler": self.collector.reward_scaler.state_dict(),
            "collector": self.collector.state_dict(),
            "envs": snapshot_vec(self.envs),
            "rng": self.rng.bit_generator.state,
            "recent": list(self.recent),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state_dict` (the config must be the same)."""
        self.agent.load_state_dict(state["agent"])
        self.optimizer.load_state_dict(state["optimizer"])
        if self.z_optimizer is not None:
            self.z_optimizer.load_state_dict(state["z_optimizer"])
        self.obs_norm.load_state_dict(state["obs_norm"])
        self.collector.reward_scaler.load_state_dict(state["reward_scaler"])
        self.collector.load_state_dict(state["collector"])
        restore_vec(self.envs, state["envs"])
        self.rng.bit_generator.state = state["rng"]
        self.recent = deque(state["recent"], maxlen=100)
        self.update, self.timesteps = int(state["update"]), int(state["timesteps"])

    def close(self) -> None:
        """Close the envs."""
        self.envs.close()


def _mean(values: Sequence[float]) -> float | None:
    """Mean, or None (JSON null) when no episode finished."""
    return float(np.mean(values)) if values else None
