"""The arms of ``acv reproduce``: the paper's cases, the no-advice and naive-shaping controls,
and the ablations, each an algorithm and the advice it trains on."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Arm:
    """One agent of the experiment.

    Attributes:
        name: folder name under ``runs/``.
        algo: the training algorithm (:data:`engine.rl.config.ALGOS`).
        advice: ``"good"`` or ``"standing"``: the advice tree it trains on (or, with
            ``advice_mode="reward"``, is compared against); None for no advice.
        title: the label in figures and tables.
        core: trained with ``seeds`` seeds (else ``extra_seeds``).
        advice_mode: F mode (:data:`engine.rl.config.ADVICE_MODES`).
        depth_factor: depth factor of F (``none`` or ``paper``).
    """

    name: str
    algo: str
    advice: str | None
    title: str
    core: bool = True
    advice_mode: str = "nearest"
    depth_factor: str = "none"

    @property
    def compared_with(self) -> str:
        """The advice tree the agent's trees are compared with."""
        return self.advice or "standing"


ARMS: tuple[Arm, ...] = (
    Arm("ppo", "ppo", None, "PPO, no advice"),
    Arm(
        "case1-paper", "bipars-em", "good", "Case 1 (paper): BiPaRS-EM, F = R", advice_mode="reward"
    ),
    Arm(
        "case1-tree",
        "bipars-em",
        "good",
        "Case 1 (tree): BiPaRS-EM, good teacher's tree",
        core=False,
    ),
    Arm("case2", "bipars-em", "standing", "Case 2: BiPaRS-EM, standing advice"),
    Arm(
        "case2-mgl",
        "bipars-mgl",
        "standing",
        "Case 2, MGL: BiPaRS-MGL, standing advice",
        core=False,
    ),
    Arm("control", "ppo-shaped", "standing", "Control: PPO + standing advice, z = 1"),
    Arm(
        "case2-paper-min",
        "bipars-em",
        "standing",
        "Ablation: Case 2 with F = paper-min",
        core=False,
        advice_mode="paper-min",
    ),
    Arm(
        "case2-paper-depth",
        "bipars-em",
        "standing",
        "Ablation: Case 2 with the paper's depth factor",
        core=False,
        depth_factor="paper",
    ),
)
