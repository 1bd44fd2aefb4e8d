"""Networks: z_phi's range and initialisation, independent stacked critics."""

from __future__ import annotations

import pytest
import torch

from engine.rl.networks import Agent, Critics, ShapingWeight


@pytest.mark.parametrize("z_init", [1.0, 0.5, -0.3])
def test_z_starts_near_z_init(z_init: float) -> None:
    torch.manual_seed(0)
    z = ShapingWeight(obs_dim=7, z_max=2.0, z_init=z_init)(torch.randn(256, 7) * 3)
    assert torch.allclose(z, torch.full_like(z, z_init), atol=0.05)


def test_z_stays_inside_its_range_for_any_input_and_weights() -> None:
    torch.manual_seed(0)
    net = ShapingWeight(obs_dim=5, z_max=2.0)
    for p in net.parameters():  # an extreme phi: pre-activations far beyond tanh's range
        torch.nn.init.normal_(p, std=100.0)
    z = net(torch.randn(1000, 5) * 1e3)
    assert (z.abs() <= 2.0).all() and z.min() < -1.9 and z.max() > 1.9


def test_stacked_critics_are_independent() -> None:
    torch.manual_seed(0)
    critics = Critics(obs_dim=6, hidden=8, n=2)
    out = critics(torch.randn(10, 6))
    assert out.shape == (2, 10) and not torch.allclose(out[0], out[1])
    out[0].sum().backward()
    assert all(float(p.grad[1].abs().sum()) == 0.0 for p in critics.parameters())
    assert all(float(p.grad[0].abs().sum()) > 0.0 for p in critics.parameters())


@pytest.mark.parametrize("algo, z", [("ppo", 0.0), ("ppo-shaped", 1.0)])
def test_fixed_z_of_the_non_bipars_algorithms(algo: str, z: float) -> None:
    agent = Agent(obs_dim=3, act_dim=2, hidden=8, algo=algo, z_max=2.0, z_init=1.0)
    assert agent.z_net is None and torch.equal(agent.z(torch.zeros(4, 3)), torch.full((4,), z))
