"""Networks: Gaussian actor, critics and the shaping-weight function z_phi (Hu et al. 2020).

All networks are CleanRL's 2x64 tanh MLPs with orthogonal initialisation.
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np
import torch
from torch import nn

LOG_2PI = math.log(2.0 * math.pi)


def layer_init(layer: nn.Linear, std: float = math.sqrt(2.0), bias: float = 0.0) -> nn.Linear:
    """Orthogonal weights with gain ``std`` and a constant bias (CleanRL, SB3)."""
    nn.init.orthogonal_(layer.weight, std)
    nn.init.constant_(layer.bias, bias)
    return layer


def mlp(n_in: int, n_out: int, hidden: int, out_std: float, out_bias: float = 0.0) -> nn.Sequential:
    """``n_in -> hidden -> hidden -> n_out`` with tanh activations."""
    return nn.Sequential(
        layer_init(nn.Linear(n_in, hidden)),
        nn.Tanh(),
        layer_init(nn.Linear(hidden, hidden)),
        nn.Tanh(),
        layer_init(nn.Linear(hidden, n_out), std=out_std, bias=out_bias),
    )


class Actor(nn.Module):
    """Diagonal Gaussian policy pi(a | s[, z]) with a state-independent log std.

    Args:
        obs_dim: observation size.
        act_dim: action size.
        hidden: hidden layer width.
        z_input: append the shaping weight z to the input (``bipars-em``'s explicit mapping).
    """

    def __init__(self, obs_dim: int, act_dim: int, hidden: int = 64, z_input: bool = False):
        super().__init__()
        self.z_input = z_input
        self.mean = mlp(obs_dim + int(z_input), act_dim, hidden, out_std=0.01)
        self.log_std = nn.Parameter(torch.zeros(act_dim))

    def forward(self, obs: torch.Tensor, z: torch.Tensor | None = None) -> torch.Tensor:
        """Action mean, shape (B, act_dim); ``z`` has shape (B,) when ``z_input``."""
        if self.z_input:
            obs = torch.cat([obs, cast(torch.Tensor, z).unsqueeze(-1)], dim=-1)
        mean: torch.Tensor = self.mean(obs)
        return mean

    def log_prob(self, mean: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """Log density of ``actions`` (B, act_dim) under N(mean, exp(log_std)^2), shape (B,)."""
        return gaussian_log_prob(mean, self.log_std, actions)

    def entropy(self) -> torch.Tensor:
        """Entropy of the Gaussian (the same for every state), a scalar."""
        return (0.5 + 0.5 * LOG_2PI + self.log_std).sum()


def gaussian_log_prob(mean: torch.Tensor, log_std: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Summed log density of a diagonal Gaussian; cheaper than ``torch.distributions``."""
    z = (x - mean) * torch.exp(-log_std)
    return -(0.5 * z.square() + log_std + 0.5 * LOG_2PI).sum(-1)


class Critics(nn.Module):
    """``n`` independent value networks V_k(s) evaluated together, output shape (n, B).

    Each critic is a 2x64 tanh MLP with its own weights; stacking them in batched matrix
    products costs about as much as one critic (BiPaRS needs two: shaped and true return).
    """

    def __init__(self, obs_dim: int, hidden: int = 64, n: int = 1):
        super().__init__()
        sizes = [
            (obs_dim, hidden, math.sqrt(2.0)),
            (hidden, hidden, math.sqrt(2.0)),
            (hidden, 1, 1.0),
        ]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for n_in, n_out, gain in sizes:
            w = torch.empty(n, n_in, n_out)
            for k in range(n):  # orthogonal per critic, as layer_init does for nn.Linear
                nn.init.orthogonal_(w[k].T, gain)
            self.weights.append(nn.Parameter(w))
            self.biases.append(nn.Parameter(torch.zeros(n, 1, n_out)))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        h = obs.expand(self.weights[0].shape[0], *obs.shape)
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = torch.baddbmm(b, h, w)
            if i < len(self.weights) - 1:
                h = torch.tanh(h)
        return h.squeeze(-1)


class ShapingWeight(nn.Module):
    """z_phi(s) = z_max * tanh(mlp(s)), initialised so that z_phi(s) is close to ``z_init``.

    The output layer has tiny weights and the bias ``atanh(z_init / z_max)``, so every state
    starts with the same trust in the advice (Hu et al. 2020 start from naive shaping, z = 1).
    """

    def __init__(self, obs_dim: int, hidden: int = 64, z_max: float = 2.0, z_init: float = 1.0):
        super().__init__()
        self.z_max = z_max
        self.net = mlp(obs_dim, 1, hidden, out_std=0.01, out_bias=float(np.arctanh(z_init / z_max)))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """z for each state, shape (B,), strictly inside (-z_max, z_max)."""
        return self.z_max * torch.tanh(self.net(obs).squeeze(-1))


class Agent(nn.Module):
    """The learner's networks: actor, critics and, for BiPaRS, z_phi.

    ``critics(obs)[0]`` estimates the return of the reward the policy optimises (R for
    ``ppo``, the shaped R + z F otherwise); BiPaRS adds ``critics(obs)[1]``, the return of R
    alone, used for the z update.
    """

    def __init__(
        self, obs_dim: int, act_dim: int, hidden: int, algo: str, z_max: float, z_init: float
    ):
        super().__init__()
        self.actor = Actor(obs_dim, act_dim, hidden, z_input=algo == "bipars-em")
        learns_z = algo.startswith("bipars")
        self.critics = Critics(obs_dim, hidden, n=2 if learns_z else 1)
        self.z_net = ShapingWeight(obs_dim, hidden, z_max, z_init) if learns_z else None
        self.fixed_z = 1.0 if algo == "ppo-shaped" else 0.0

    def z(self, obs: torch.Tensor) -> torch.Tensor:
        """Shaping weight per state, shape (B,): z_phi(s), or the algorithm's constant."""
        if self.z_net is None:
            return torch.full(obs.shape[:1], self.fixed_z)
        z: torch.Tensor = self.z_net(obs)
        return z

    def policy_params(self) -> list[nn.Parameter]:
        """Parameters trained by the PPO loss (actor and critics, not z_phi)."""
        return [*self.actor.parameters(), *self.critics.parameters()]

    def values(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Shaped and true state values, each shape (B,) (the same tensor without BiPaRS)."""
        v = self.critics(obs)
        return v[0], v[-1]
