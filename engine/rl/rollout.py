"""Collecting rollouts from the vector env, with the episode statistics the run logs."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from numpy.typing import ArrayLike

from engine.gym_types import box
from engine.rl.buffer import Rollout
from engine.rl.inference import NumpyAgent
from engine.rl.networks import Agent
from engine.rl.normalize import ObsNormalizer, RewardScaler
from engine.rl.shaping import AdviceShaping


@dataclass
class EpisodeStats:
    """Episodes finished during one rollout: raw true and shaped returns, lengths."""

    true_returns: list[float] = field(default_factory=list)
    shaped_returns: list[float] = field(default_factory=list)
    lengths: list[int] = field(default_factory=list)


class Collector:
    """Steps the vector env with the current policy and fills a :class:`Rollout`.

    It owns the env's running state between rollouts (the last observation and the returns
    of unfinished episodes), so that a checkpoint can save and restore it exactly.

    Args:
        envs: the :func:`engine.rl.vecenv.make_vec_env` env, already reset.
        first_obs: the observation returned by that reset, shape (N, obs_dim).
        agent: the learner's networks.
        obs_norm: observation normaliser (updated with every observation seen).
        reward_scaler: scales R and F by the running std of the discounted return.
        gamma: discount of the truncation bootstrap.
        rng: source of the Gaussian action noise.
    """

    def __init__(
        self,
        envs: AdviceShaping,
        first_obs: np.ndarray,
        agent: Agent,
        obs_norm: ObsNormalizer,
        reward_scaler: RewardScaler,
        gamma: float,
        rng: np.random.Generator,
    ):
        self.envs, self.agent, self.gamma, self.rng = envs, agent, gamma, rng
        self.obs_norm, self.reward_scaler = obs_norm, reward_scaler
        self.next_obs = first_obs
        n = envs.num_envs
        self.ep_true, self.ep_shaped, self.ep_len = np.zeros(n), np.zeros(n), np.zeros(n, int)
        space = box(envs.single_action_space)
        self.low, self.high = space.low, space.high

    def _policy(self, net: NumpyAgent, obs: np.ndarray) -> dict[str, np.ndarray]:
        z = net.z(obs)
        mean = net.mean(obs, z)
        actions = mean + self.rng.standard_normal(mean.shape, dtype=np.float32) * np.exp(
            net.log_std
        )
        values, true_values = net.values(obs)
        return {
            "z": z,
            "actions": actions,
            "logprobs": net.log_prob(mean, actions),
            "values": values,
            "true_values": true_values,
        }

    def _normalise(self, raw: np.ndarray) -> np.ndarray:
        self.obs_norm.update(raw)
        return self.obs_norm(raw)

    def collect(self, num_steps: int) -> tuple[Rollout, EpisodeStats, dict[str, float]]:
        """Run ``num_steps`` vector steps; return the rollout, finished episodes, F/z stats."""
        net = NumpyAgent(self.agent)
        buf: dict[str, list[np.ndarray]] = {}
        stats = EpisodeStats()
        raw_advice = []
        obs = self._normalise(self.next_obs)
        for _ in range(num_steps):
            out = self._policy(net, obs)
            self.next_obs, reward, terminated, truncated, info = self.envs.step(
                out["actions"].clip(self.low, self.high)
            )
            out |= self._rewards(net, reward, info["advice"], terminated, truncated, info)
            out["obs"] = obs
            for key, value in out.items():
                buf.setdefault(key, []).append(value)
            self._track(reward, info["advice"], out["z"], terminated | truncated, stats)
            raw_advice.append(info["advice"])
            obs = self._normalise(self.next_obs)
        last = self._policy(net, obs)

        def as_tensor(x: ArrayLike) -> torch.Tensor:
            return torch.from_numpy(np.asarray(x, dtype=np.float32))

        rollout = Rollout(
            **{k: as_tensor(np.stack(v)) for k, v in buf.items()},
            last_obs=as_tensor(obs),
            last_values=as_tensor(last["values"]),
            last_true_values=as_tensor(last["true_values"]),
        )
        return rollout, stats, _spread(np.concatenate(raw_advice), rollout.z.numpy())

    def _rewards(
        self,
        net: NumpyAgent,
        reward: np.ndarray,
        advice: np.ndarray,
        terminated: np.ndarray,
        truncated: np.ndarray,
        info: dict[str, Any],
    ) -> dict[str, np.ndarray]:
        """Scaled rewards of one step, and the value of the final obs of truncated episodes."""
        done = terminated | truncated
        self.reward_scaler.update(reward, done)
        boot_shaped, boot_true = np.zeros(len(reward)), np.zeros(len(reward))
        cut = np.flatnonzero(truncated & ~terminated)
        if cut.size:  # a time limit is not a terminal state: bootstrap (as SB3 does)
            final = self.obs_norm(np.stack(info["final_obs"][cut]))
            values, true_values = net.values(final)
            boot_shaped[cut], boot_true[cut] = self.gamma * values, self.gamma * true_values
        return {
            "env_reward": self.reward_scaler(reward),
            "advice": self.reward_scaler(advice),
            "boot_shaped": boot_shaped,
            "boot_true": boot_true,
            "dones": done,
        }

    def _track(
        self,
        reward: np.ndarray,
        advice: np.ndarray,
        z: np.ndarray,
        done: np.ndarray,
        stats: EpisodeStats,
    ) -> None:
        """Accumulate raw (unscaled) episode returns; record the episodes that ended."""
        self.ep_true += reward
        self.ep_shaped += reward + z * advice
        self.ep_len += 1
        for i in np.flatnonzero(done):
            stats.true_returns.append(float(self.ep_true[i]))
            stats.shaped_returns.append(float(self.ep_shaped[i]))
            stats.lengths.append(int(self.ep_len[i]))
        self.ep_true[done], self.ep_shaped[done], self.ep_len[done] = 0.0, 0.0, 0

    def state_dict(self) -> dict[str, Any]:
        """Running state between rollouts (the env snapshots are saved separately)."""
        return {
            "next_obs": torch.from_numpy(self.next_obs.copy()),
            "ep_true": self.ep_true.tolist(),
            "ep_shaped": self.ep_shaped.tolist(),
            "ep_len": self.ep_len.tolist(),
            "rng": self.rng.bit_generator.state,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.next_obs = state["next_obs"].numpy().copy()
        self.ep_true = np.asarray(state["ep_true"], dtype=np.float64)
        self.ep_shaped = np.asarray(state["ep_shaped"], dtype=np.float64)
        self.ep_len = np.asarray(state["ep_len"], dtype=int)
        self.rng.bit_generator.state = state["rng"]


def _spread(advice: np.ndarray, z: np.ndarray) -> dict[str, float]:
    """Mean and standard deviation of F (raw, after ``advice_scale``) and z over the batch."""
    return {
        "f_mean": float(advice.mean()),
        "f_std": float(advice.std()),
        "z_mean": float(z.mean()),
        "z_std": float(z.std()),
    }
