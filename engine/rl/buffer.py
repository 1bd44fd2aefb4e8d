"""Rollout storage and generalised advantage estimation (Schulman et al. 2016)."""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class Rollout:
    """One rollout of ``T`` steps in ``N`` envs; rewards are already scaled.

    Attributes:
        obs: normalised observations s_t, shape (T, N, obs_dim).
        actions: unclipped Gaussian samples a_t, shape (T, N, act_dim).
        logprobs: log pi_old(a_t | s_t[, z_t]), shape (T, N).
        z: shaping weight used at s_t, shape (T, N).
        values: shaped critic V(s_t), shape (T, N).
        true_values: true critic V_R(s_t), shape (T, N) (equal to ``values`` without one).
        env_reward: scaled environment reward R_t, shape (T, N).
        advice: scaled advice F(s_{t+1}), shape (T, N).
        boot_shaped: gamma * V(final obs) where the episode was truncated, else 0, (T, N).
        boot_true: the same with the true critic, shape (T, N).
        dones: 1.0 where the episode ended after step t, shape (T, N).
        last_obs: s_T, shape (N, obs_dim); ``last_values``/``last_true_values``: V(s_T), (N,).
    """

    obs: torch.Tensor
    actions: torch.Tensor
    logprobs: torch.Tensor
    z: torch.Tensor
    values: torch.Tensor
    true_values: torch.Tensor
    env_reward: torch.Tensor
    advice: torch.Tensor
    boot_shaped: torch.Tensor
    boot_true: torch.Tensor
    dones: torch.Tensor
    last_obs: torch.Tensor
    last_values: torch.Tensor
    last_true_values: torch.Tensor

    @property
    def shaped_reward(self) -> torch.Tensor:
        """R_t + z_t F(s_{t+1}) plus the truncation bootstrap, shape (T, N)."""
        return self.env_reward + self.z * self.advice + self.boot_shaped

    @property
    def true_reward(self) -> torch.Tensor:
        """R_t plus the truncation bootstrap of the true critic, shape (T, N)."""
        return self.env_reward + self.boot_true


def gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    dones: torch.Tensor,
    last_values: torch.Tensor,
    gamma: float,
    lam: float,
) -> torch.Tensor:
    """Generalised advantage estimates, shape (T, N).

    Args:
        rewards: r_t, shape (T, N) (differentiable: BiPaRS-MGL back-propagates through it).
        values: V(s_t), shape (T, N).
        dones: 1.0 where the episode ended after step t (no bootstrap from s_{t+1}), (T, N).
        last_values: V(s_T) of the observation after the rollout, shape (N,).
        gamma: discount factor.
        lam: GAE lambda.
    """
    not_done = 1.0 - dones
    next_values = torch.cat([values[1:], last_values.unsqueeze(0)]) * not_done
    deltas = rewards + gamma * next_values - values
    advantages = []
    running = torch.zeros_like(last_values)
    for t in reversed(range(rewards.shape[0])):
        running = deltas[t] + gamma * lam * not_done[t] * running
        advantages.append(running)
    return torch.stack(advantages[::-1])
