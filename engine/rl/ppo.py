"""The PPO update (Schulman et al. 2017), CleanRL's ``ppo_continuous_action`` in function form."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass
from typing import cast

import numpy as np
import torch
from torch import nn

from engine.rl.buffer import Rollout, gae
from engine.rl.config import TrainConfig
from engine.rl.networks import Agent
from engine.rl.optim import flat_step, flat_zero_grad


@dataclass(frozen=True)
class Batch:
    """A rollout flattened to ``B = T * N`` transitions, with returns and advantages.

    Attributes:
        obs: (B, obs_dim); actions: (B, act_dim); logprobs, z: (B,).
        advantages, returns, values: of the shaped reward (R for ``ppo``), shape (B,).
        true_advantages, true_returns, true_values: of the environment reward R, shape (B,).
    """

    obs: torch.Tensor
    actions: torch.Tensor
    logprobs: torch.Tensor
    z: torch.Tensor
    advantages: torch.Tensor
    returns: torch.Tensor
    values: torch.Tensor
    true_advantages: torch.Tensor
    true_returns: torch.Tensor
    true_values: torch.Tensor


def make_batch(rollout: Rollout, cfg: TrainConfig) -> Batch:
    """GAE for both critics (side by side in one pass) and flattening of the rollout."""
    both = gae(
        torch.cat([rollout.shaped_reward, rollout.true_reward], 1),
        torch.cat([rollout.values, rollout.true_values], 1),
        rollout.dones.repeat(1, 2),
        torch.cat([rollout.last_values, rollout.last_true_values]),
        cfg.gamma,
        cfg.gae_lambda,
    )
    adv, true_adv = both.chunk(2, dim=1)

    def flat(x: torch.Tensor) -> torch.Tensor:
        return x.reshape(-1, *x.shape[2:])

    return Batch(
        obs=flat(rollout.obs),
        actions=flat(rollout.actions),
        logprobs=flat(rollout.logprobs),
        z=flat(rollout.z),
        advantages=flat(adv),
        returns=flat(adv + rollout.values),
        values=flat(rollout.values),
        true_advantages=flat(true_adv),
        true_returns=flat(true_adv + rollout.true_values),
        true_values=flat(rollout.true_values),
    )


def normalise(x: torch.Tensor) -> torch.Tensor:
    """Zero mean, unit std (advantage normalisation per minibatch)."""
    return (x - x.mean()) / (x.std() + 1e-8)


def clipped_surrogate(ratio: torch.Tensor, advantages: torch.Tensor, clip: float) -> torch.Tensor:
    """PPO's clipped policy loss (to minimise), a scalar."""
    return -torch.min(advantages * ratio, advantages * ratio.clamp(1 - clip, 1 + clip)).mean()


def value_loss(
    new: torch.Tensor, old: torch.Tensor, returns: torch.Tensor, clip: float
) -> torch.Tensor:
    """CleanRL's clipped value loss, ``0.5 * max(unclipped, clipped)`` squared errors."""
    clipped = old + (new - old).clamp(-clip, clip)
    return 0.5 * torch.max((new - returns).square(), (clipped - returns).square()).mean()


def minibatches(batch: Batch, minibatch_size: int, rng: np.random.Generator) -> Iterator[Batch]:
    """A random partition of ``batch`` into minibatches (one gather, then cheap slices)."""
    order = torch.from_numpy(rng.permutation(len(batch.obs)))
    fields = [f.name for f in dataclasses.fields(Batch)]
    shuffled = [getattr(batch, name)[order] for name in fields]
    for start in range(0, len(order) - minibatch_size + 1, minibatch_size):
        yield Batch(*(x[start : start + minibatch_size] for x in shuffled))


def ppo_loss(
    agent: Agent, mb: Batch, cfg: TrainConfig
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Total PPO loss of one minibatch (policy + critics - entropy) and its parts."""
    mean = agent.actor(mb.obs, mb.z)
    ratio = (agent.actor.log_prob(mean, mb.actions) - mb.logprobs).exp()
    pg_loss = clipped_surrogate(ratio, normalise(mb.advantages), cfg.clip_coef)
    values, true_values = agent.values(mb.obs)
    v_loss = value_loss(values, mb.values, mb.returns, cfg.clip_coef)
    if cfg.ent_coef:
        entropy = agent.actor.entropy()
        loss = pg_loss - cfg.ent_coef * entropy + cfg.vf_coef * v_loss
    else:  # the same loss and gradients, bit for bit, without the term's graph
        with torch.no_grad():
            entropy = agent.actor.entropy()
        loss = pg_loss + cfg.vf_coef * v_loss
    parts = {"policy_loss": pg_loss, "value_loss": v_loss, "entropy": entropy}
    if agent.z_net is not None:
        tv_loss = value_loss(true_values, mb.true_values, mb.true_returns, cfg.clip_coef)
        loss = loss + cfg.vf_coef * tv_loss
        parts["true_value_loss"] = tv_loss
    return loss, parts


def ppo_update(
    agent: Agent,
    optimizer: torch.optim.Optimizer,
    batch: Batch,
    cfg: TrainConfig,
    rng: np.random.Generator,
) -> dict[str, float]:
    """``update_epochs`` passes of minibatch Adam steps; returns the mean of each loss part.

    ``optimizer`` holds the actor and critics, possibly flattened (:mod:`engine.rl.optim`).
    """
    params = [p for group in optimizer.param_groups for p in group["params"]]
    history = []
    for _ in range(cfg.update_epochs):
        for mb in minibatches(batch, cfg.minibatch_size, rng):
            loss, parts = ppo_loss(agent, mb, cfg)
            flat_zero_grad(optimizer)  # keeps flat gradient views in place
            loss.backward()
            clip_grad_norm(params, cfg.max_grad_norm)
            flat_step(optimizer)
            history.append(torch.stack([p.detach() for p in parts.values()]))
    means = torch.stack(history).mean(0).tolist()
    return dict(zip(parts, means, strict=True)) | diagnostics(agent, batch, cfg)


def clip_grad_norm(params: list[torch.Tensor], max_norm: float) -> None:
    """``nn.utils.clip_grad_norm_``, with a three-op fast path for one flat parameter (on a
    gradient, which needs no ``no_grad``: it records no graph)."""
    if len(params) != 1:
        nn.utils.clip_grad_norm_(params, max_norm, foreach=True)
        return
    grad = cast(torch.Tensor, params[0].grad)  # zero_grad(set_to_none=False) keeps it
    grad.mul_((max_norm / (grad.norm() + 1e-6)).clamp_(max=1.0))


@torch.no_grad()
def diagnostics(agent: Agent, batch: Batch, cfg: TrainConfig) -> dict[str, float]:
    """How far the whole update moved the policy, on the full batch (one pass, no graph).

    ``approx_kl`` (Schulman's k3 estimator) and ``clipfrac`` compare the updated policy with
    the one that collected the batch; ``explained_variance`` is that of the old values.
    """
    logratio = agent.actor.log_prob(agent.actor(batch.obs, batch.z), batch.actions) - batch.logprobs
    ratio = logratio.exp()
    return {
        "approx_kl": float(((ratio - 1) - logratio).mean()),
        "clipfrac": float(((ratio - 1.0).abs() > cfg.clip_coef).float().mean()),
        "explained_variance": explained_variance(batch.values, batch.returns),
    }


def explained_variance(pred: torch.Tensor, target: torch.Tensor) -> float:
    """1 - Var(target - pred) / Var(target); NaN when the target is constant."""
    var = float(target.var())
    return float("nan") if var == 0 else 1.0 - float((target - pred).var()) / var
