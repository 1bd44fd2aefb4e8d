"""Record types that the web tier reads from a checkpoint's stored report.

Torch- and MuJoCo-free, so that the server that only reads artefacts imports them without
the training stack (``tests/app/platform/test_web_without_torch.py``); the executor writes them
(:mod:`engine.rl.report`) and the app derives its response bodies from them.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class CandidateRow:
    """One candidate as the agent sees it at a checkpoint.

    Attributes:
        id: the candidate's id in the bracket.
        reward: R(s) as the shaped judge uses it: the stored ``env_reward`` minus the control
            cost of the policy's mean action in s.
        advice: F(s) after ``advice_scale`` (F = R for advice mode ``reward``; 0 for ``ppo``).
        z: the shaping weight z_phi(s) (0 for ``ppo``, 1 for ``ppo-shaped``).
        shaping: ``z * advice``, the ``shaping`` judge's score.
        shaped: ``reward + shaping``, the ``shaped`` judge's score.
        value: V(s) of the shaped critic, the ``shaped-value`` judge's score.
        behaviour: the agent's mean occupancy near s, the ``behaviour`` judge's score.
        env_return: the mean return-to-go of the agent's policy from s, the ``return``
            judge's score (None in reports stored before that judge).
    """

    id: int
    reward: float
    advice: float
    z: float
    shaping: float
    shaped: float
    value: float
    behaviour: float
    env_return: float | None = None
