"""Generalised advantage estimation against hand-computed values."""

from __future__ import annotations

import pytest
import torch

from engine.rl.buffer import gae


def test_gae_matches_hand_computation() -> None:
    # one env, 3 steps; the episode ends after step 1 (no bootstrap from s_2 into step 1)
    rewards = torch.tensor([[1.0], [2.0], [3.0]])
    values = torch.tensor([[0.5], [1.0], [1.5]])
    dones = torch.tensor([[0.0], [1.0], [0.0]])
    last = torch.tensor([2.0])
    g, lam = 0.9, 0.8
    d2 = 3.0 + g * 2.0 - 1.5  # 4.3
    d1 = 2.0 - 1.0  # 1.0 (terminal)
    d0 = 1.0 + g * 1.0 - 0.5  # 1.4
    expected = torch.tensor([[d0 + g * lam * d1], [d1], [d2]])
    assert torch.allclose(gae(rewards, values, dones, last, g, lam), expected)


def test_gae_with_lambda_one_is_return_minus_value() -> None:
    rewards = torch.tensor([[1.0, 0.0], [1.0, 1.0], [1.0, 2.0]])
    values = torch.tensor([[0.3, 0.1], [0.2, 0.4], [0.1, 0.2]])
    dones = torch.zeros(3, 2)
    last = torch.tensor([5.0, -1.0])
    g = 0.5
    returns = torch.zeros(3, 2)
    running = last
    for t in (2, 1, 0):
        running = rewards[t] + g * running
        returns[t] = running
    assert torch.allclose(gae(rewards, values, dones, last, g, 1.0), returns - values)


@pytest.mark.parametrize("lam", [0.0, 0.95])
def test_gae_is_differentiable_in_the_rewards(lam: float) -> None:
    rewards = torch.ones(4, 2, requires_grad=True)
    adv = gae(rewards, torch.zeros(4, 2), torch.zeros(4, 2), torch.zeros(2), 0.99, lam)
    adv.sum().backward()
    assert rewards.grad is not None and (rewards.grad > 0).all()
