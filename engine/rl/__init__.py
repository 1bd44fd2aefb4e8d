"""Training with advice: PPO plus a learned shaping weight (BiPaRS, Hu et al. 2020).

The agent maximises R(s, a) + z_phi(s) F(s), where F is the advice reward of a Human
Preference Tree and z_phi(s) how much the agent trusts it (paper, section III). Algorithms:
``ppo`` (R only), ``ppo-shaped`` (z = 1), ``bipars-em`` and ``bipars-mgl`` (learned z).

Public API (imported lazily, so that ``engine.rl.config`` stays free of torch):

- :class:`~engine.rl.config.TrainConfig`, :data:`~engine.rl.config.ALGOS`
- :func:`~engine.rl.runner.train`: a whole run as a library call (progress, cancel, resume)
- :func:`~engine.rl.agent_judge.agent_tree`: the Agent Preference Tree of a checkpoint
- :func:`~engine.rl.plot.plot_runs`: learning curves

Modules: ``networks`` (actor, critics, z_phi), ``normalize``, ``shaping``, ``advice_fn`` (F
of a run's trees), ``vecenv``, ``split_vecenv``, ``envproc`` and ``env_snapshot`` (env side),
``rollout``, ``buffer`` (GAE), ``ppo``, ``bipars``, ``trainer`` (one iteration),
``checkpoint``, ``logger``, ``runner``, ``agent_judge`` and ``reward_terms``, ``plot``.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

_EXPORTS = {
    "TrainConfig": "config",
    "ALGOS": "config",
    "train": "runner",
    "agent_tree": "agent_judge",
    "plot_runs": "plot",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(import_module(f"engine.rl.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'engine.rl' has no attribute {name!r}")
