"""F, the advice reward a run trains with, built from its trees with its config's options.

:func:`advice_reward` builds F from one Human Preference Tree, :func:`pool_reward` from pooled
trees; both give F = R (:class:`~engine.rl.shaping.EnvRewardAdvice`) for the ``reward`` advice
mode. :func:`engine.rl.runner.train` shapes its run with it, and the agent's judges evaluate
the F the agent trained with (:mod:`engine.rl.agent_judge`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import cast

from engine.advice import AdviceMode, AdviceReward
from engine.rl.config import REWARD_ADVICE, TrainConfig
from engine.rl.shaping import AdviceFn, EnvRewardAdvice
from engine.treefile import TreeDocument


def pool_reward(config: TrainConfig, docs: Sequence[TreeDocument]) -> AdviceFn:
    """F of pooled advice: the mean of the trees' F with the config's options, weighted by
    its ``pool_weights`` when set (F = R for the ``reward`` mode, whatever the trees)."""
    from engine.pooling import pooled_advice

    if config.advice_mode == REWARD_ADVICE:
        return EnvRewardAdvice()
    return pooled_advice(
        docs,
        config.advice_mode,
        config.advice_depth_factor,
        config.advice_kappa,
        weights=config.pool_weights,
    )


def advice_reward(config: TrainConfig, doc: TreeDocument) -> AdviceFn:
    """F built from a tree with the config's mode, depth factor and kappa (F = R for the
    ``reward`` mode, whatever the tree)."""
    if config.advice_mode == REWARD_ADVICE:
        return EnvRewardAdvice()
    # TrainConfig.__post_init__ has checked that the mode is one of ADVICE_MODES
    return AdviceReward.from_tree(
        doc,
        mode=cast(AdviceMode, config.advice_mode),
        depth_factor=config.advice_depth_factor,
        kappa=config.advice_kappa,
    )
