"""The PPO update on a fixed batch."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from engine.rl.config import TrainConfig
from engine.rl.networks import Agent
from engine.rl.ppo import Batch, clipped_surrogate, ppo_loss, ppo_update


def fixed_batch(agent: Agent, n: int, obs_dim: int, act_dim: int) -> Batch:
    """Random transitions whose returns depend on the observation (learnable)."""
    g = torch.Generator().manual_seed(0)
    obs = torch.randn(n, obs_dim, generator=g)
    z = agent.z(obs).detach()
    with torch.no_grad():
        mean = agent.actor(obs, z)
        actions = mean + torch.randn(n, act_dim, generator=g)
        logprobs = agent.actor.log_prob(mean, actions)
        values, true_values = agent.values(obs)
    adv = actions[:, 0] * obs[:, 0]  # favours actions aligned with the first feature
    returns = obs[:, 1] * 3.0
    return Batch(obs, actions, logprobs, z, adv, returns, values, adv, returns, true_values)


@pytest.mark.parametrize("algo", ["ppo", "bipars-em"])
def test_one_update_lowers_the_loss_on_a_fixed_batch(algo: str) -> None:
    torch.manual_seed(0)
    cfg = TrainConfig(
        algo=algo, n_envs=1, num_steps=256, num_minibatches=1, update_epochs=1, learning_rate=1e-2
    )
    agent = Agent(4, 2, 16, algo, cfg.z_max, cfg.z_init)
    batch = fixed_batch(agent, 256, 4, 2)
    before = ppo_loss(agent, batch, cfg)[0].item()
    optimizer = torch.optim.Adam(agent.policy_params(), lr=cfg.learning_rate)
    out = ppo_update(agent, optimizer, batch, cfg, np.random.default_rng(0))
    after = ppo_loss(agent, batch, cfg)[0].item()
    assert after < before
    assert {
        "policy_loss",
        "value_loss",
        "entropy",
        "approx_kl",
        "clipfrac",
        "explained_variance",
    } <= set(out)
    assert ("true_value_loss" in out) == (algo == "bipars-em")


def test_clipped_surrogate_ignores_ratio_gains_beyond_the_clip() -> None:
    adv = torch.tensor([1.0, -1.0])
    assert float(clipped_surrogate(torch.tensor([1.5, 1.0]), adv, 0.2)) == pytest.approx(
        -(1.2 - 1.0) / 2
    )
    # a pessimistic bound: a negative advantage with a large ratio is not clipped
    assert float(clipped_surrogate(torch.tensor([1.0, 3.0]), adv, 0.2)) == pytest.approx(
        -(1.0 - 3.0) / 2
    )
