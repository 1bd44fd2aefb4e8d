"""The shared dataset's ``preferences`` table (issue 44 §5): each answered pair as reward
learning reads it, the ``chosen`` and the ``rejected`` state side by side as arrays, so that a
Bradley-Terry reward model (``examples/bradley_terry.py``) needs no join with ``candidates``
and no MuJoCo.

A state's features are the two that ACV itself reads: its posture, the part of ``qpos`` that
the advice reward F compares (:func:`engine.rewards.posture_features`), and the observation
an agent sees there (:func:`engine.envs.restore`). The rows come from the export's ``labels``
table, so they hold the same consenting participants under the same pseudonyms.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from app.models import Candidate
from engine.envs import env_model, make_env, restore
from engine.rewards import posture_features

Rows = list[dict[str, Any]]
#: A label records what its pair showed (``still``, or ``clip`` in a study with clips,
#: issue 41 §3); a row without one answered two still pictures.
STILL = "still"


def preferences(labels: Rows, candidates: Sequence[Candidate], env_id: str) -> Rows:
    """One row of :data:`app.labelling.dataset_tables.PREFERENCES` per row of ``labels``.

    Args:
        labels: the export's ``labels`` rows (pseudonymous, consenting participants only).
        candidates: every candidate of the study.
        env_id: the study's env, which turns a state into its observation.
    """
    states = state_features(candidates, env_id)
    rows = []
    for label in labels:
        chosen = label["winner"]
        rejected = label["right"] if chosen == label["left"] else label["left"]
        rows.append(
            {
                "participant": label["participant"],
                "kind": label["kind"],
                "stimulus": label.get("stimulus", STILL),
                "chosen": chosen,
                "rejected": rejected,
                "tie": label["tie"],
            }
            | _side("chosen", states[chosen])
            | _side("rejected", states[rejected])
        )
    return rows


def _side(name: str, features: tuple[list[float], list[float]]) -> dict[str, list[float]]:
    posture, observation = features
    return {f"{name}_posture": posture, f"{name}_observation": observation}


def state_features(
    candidates: Sequence[Candidate], env_id: str
) -> dict[int, tuple[list[float], list[float]]]:
    """Candidate id -> its posture features and its observation.

    The observations come from one env that restores states and never steps, so each
    depends on its state alone, in any order (a stepped env's last action and solver warm
    start would leak into Humanoid's contact forces).
    """
    qpos = np.array([c.qpos for c in candidates], dtype=np.float64)
    postures = posture_features(qpos, env_model(env_id))
    env = make_env(env_id)
    try:
        observations = [restore(env, np.array(c.qpos), np.array(c.qvel)) for c in candidates]
    finally:
        env.close()
    return {
        c.id: (posture.tolist(), observation.tolist())
        for c, posture, observation in zip(candidates, postures, observations, strict=True)
    }
