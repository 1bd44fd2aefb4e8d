"""The agent's forward pass in numpy, for acting in the env one small batch at a time.

A rollout evaluates the networks on ``n_envs`` observations per step, where torch's per-op
dispatch costs more than the arithmetic. Numpy views of the torch parameters (shared memory,
so they follow the in-place optimiser updates) make that step several times cheaper. The
update still runs in torch; the ratio pi_new / pi_old starts at 1 up to float rounding.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from engine.rl.networks import LOG_2PI, Agent

Layers = list[tuple[np.ndarray, np.ndarray]]


def _view(t: torch.Tensor) -> np.ndarray:
    return t.detach().numpy()


def _linear_layers(seq: nn.Sequential) -> Layers:
    """(W^T, b) views of the Linear layers of an :func:`engine.rl.networks.mlp`."""
    return [(_view(m.weight).T, _view(m.bias)) for m in seq if isinstance(m, nn.Linear)]


def mlp_forward(layers: Layers, x: np.ndarray) -> np.ndarray:
    """Tanh MLP; stacked (n, in, out) weights broadcast to an (n, B, out) result."""
    for i, (w, b) in enumerate(layers):
        x = x @ w + b
        if i < len(layers) - 1:
            np.tanh(x, out=x)
    return x


class NumpyAgent:
    """Acting with an :class:`~engine.rl.networks.Agent`: z, action mean and values.

    Build one per rollout (views are cheap); it reads the parameters' current values.
    """

    def __init__(self, agent: Agent):
        self.actor = _linear_layers(agent.actor.mean)
        self.z_input = agent.actor.z_input
        self.log_std = _view(agent.actor.log_std)
        self.critics = [
            (_view(w), _view(b))
            for w, b in zip(agent.critics.weights, agent.critics.biases, strict=True)
        ]
        self.z_net = None if agent.z_net is None else _linear_layers(agent.z_net.net)
        self.z_max = 0.0 if agent.z_net is None else agent.z_net.z_max
        self.fixed_z = np.float32(agent.fixed_z)

    def z(self, obs: np.ndarray) -> np.ndarray:
        """Shaping weight per state, shape (B,)."""
        if self.z_net is None:
            return np.full(len(obs), self.fixed_z, dtype=np.float32)
        z: np.ndarray = self.z_max * np.tanh(mlp_forward(self.z_net, obs)[:, 0])
        return z

    def mean(self, obs: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Action mean, shape (B, act_dim)."""
        if self.z_input:
            obs = np.concatenate([obs, z[:, None]], axis=1)
        return mlp_forward(self.actor, obs)

    def values(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Shaped and true values, each shape (B,)."""
        v = mlp_forward(self.critics, obs)[..., 0]
        return v[0], v[-1]

    def log_prob(self, mean: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Log density of ``actions`` under the Gaussian policy, shape (B,)."""
        u = (actions - mean) * np.exp(-self.log_std)
        log_prob: np.ndarray = -(0.5 * u * u + self.log_std + 0.5 * LOG_2PI).sum(-1)
        return log_prob
