"""Updates of the shaping weight z_phi (Hu et al. 2020, "Learning to Utilize Shaping Rewards").

BiPaRS is a bi-level problem: the policy maximises the shaped return R + z_phi(s) F(s); z_phi
maximises the *true* return of that policy. Both variants here take one gradient step on phi
after each PPO update, always with the true-return advantages.
"""

from __future__ import annotations

from typing import cast

import numpy as np
import torch
from torch.func import functional_call

from engine.rl.buffer import Rollout, gae
from engine.rl.config import TrainConfig
from engine.rl.networks import Agent, ShapingWeight, gaussian_log_prob
from engine.rl.ppo import Batch, clipped_surrogate, normalise


def em_update(
    agent: Agent, z_optimizer: torch.optim.Optimizer, batch: Batch, cfg: TrainConfig
) -> dict[str, float]:
    """Explicit mapping (BiPaRS-EM): the policy pi(a | s, z) takes z as input.

    The true-return clipped surrogate is differentiated through pi's dependence on
    z = z_phi(s) only (the actor's own parameters are left untouched):
    grad_phi J = E[grad_z log pi(a | s, z) grad_phi z_phi(s) A_R(s, a)]. Each of the
    ``z_epochs`` steps uses the whole batch: z_phi moves slowly and the true advantages are
    noisy, so one low-variance step per rollout beats many minibatch steps.
    """
    losses = []
    advantages = normalise(batch.true_advantages)
    for _ in range(cfg.z_epochs):
        mean = agent.actor(batch.obs, _z_net(agent)(batch.obs))
        ratio = (agent.actor.log_prob(mean, batch.actions) - batch.logprobs).exp()
        loss = clipped_surrogate(ratio, advantages, cfg.clip_coef)
        _step(z_optimizer, loss, agent, cfg)
        losses.append(loss.item())
    return {"z_loss": float(np.mean(losses))}


def _step(
    z_optimizer: torch.optim.Optimizer, loss: torch.Tensor, agent: Agent, cfg: TrainConfig
) -> None:
    """One clipped-gradient Adam step on phi only (the actor's gradients are not touched)."""
    z_optimizer.zero_grad(set_to_none=False)  # keeps flat gradient views in place
    loss.backward(inputs=list(_z_net(agent).parameters()))
    params = [p for group in z_optimizer.param_groups for p in group["params"]]
    torch.nn.utils.clip_grad_norm_(params, cfg.max_grad_norm)
    z_optimizer.step()


def _z_net(agent: Agent) -> ShapingWeight:
    """z_phi, which :class:`Agent` makes for both bipars-* algorithms."""
    return cast(ShapingWeight, agent.z_net)


def shaped_advantages(rollout: Rollout, z: torch.Tensor, cfg: TrainConfig) -> torch.Tensor:
    """Shaped-reward GAE with ``z`` (shape (T, N), differentiable) in place of the rollout's z."""
    rewards = rollout.env_reward + z * rollout.advice + rollout.boot_shaped
    return gae(
        rewards, rollout.values, rollout.dones, rollout.last_values, cfg.gamma, cfg.gae_lambda
    )


def mgl_update(
    agent: Agent,
    z_optimizer: torch.optim.Optimizer,
    rollout: Rollout,
    batch: Batch,
    cfg: TrainConfig,
    theta: dict[str, torch.Tensor],
) -> dict[str, float]:
    """One-step meta-gradient (BiPaRS-MGL) of the true-return objective w.r.t. phi.

    With theta the actor that collected the rollout, theta' = theta + meta_lr *
    grad_theta J_shaped(theta, phi), where J_shaped's advantages keep z_phi(s) F(s) in the graph
    (GAE is linear in the rewards); phi then ascends J_R(theta'), the true-return surrogate at
    theta' (Hu et al. 2020, section 4.2). ``z_epochs`` full-batch steps; torch.func
    evaluates the actor at theta and theta'.

    Args:
        theta: the actor's parameters before this rollout's PPO update (detached copies).
    """
    losses = []
    true_adv = normalise(batch.true_advantages)
    params = {k: v.detach().requires_grad_() for k, v in theta.items()}
    for _ in range(cfg.z_epochs):
        inner = _surrogate(agent, params, batch, _meta_advantages(agent, rollout, cfg))
        grads = torch.autograd.grad(inner, list(params.values()), create_graph=True)
        updated = {k: v - cfg.meta_lr * g for (k, v), g in zip(params.items(), grads, strict=True)}
        outer = _surrogate(agent, updated, batch, true_adv)
        _step(z_optimizer, outer, agent, cfg)
        losses.append(outer.item())
    return {"z_loss": float(np.mean(losses))}


def _meta_advantages(agent: Agent, rollout: Rollout, cfg: TrainConfig) -> torch.Tensor:
    """Normalised shaped advantages of the whole batch as a function of phi, shape (B,)."""
    z = _z_net(agent)(rollout.obs.reshape(-1, rollout.obs.shape[-1])).view(rollout.z.shape)
    adv = shaped_advantages(rollout, z, cfg).reshape(-1)
    # centre inside the graph (a common shift of z is no signal), scale by a constant
    return (adv - adv.mean()) / (adv.std().detach() + 1e-8)


def _surrogate(
    agent: Agent, params: dict[str, torch.Tensor], batch: Batch, advantages: torch.Tensor
) -> torch.Tensor:
    """Importance-weighted policy-gradient loss of the actor evaluated with ``params``.

    Unclipped: near theta the ratios are close to 1, and clipping would only zero gradients.
    """
    mean = functional_call(agent.actor, params, (batch.obs, batch.z))
    logp = gaussian_log_prob(mean, params["log_std"], batch.actions)
    return -((logp - batch.logprobs).exp() * advantages).mean()
