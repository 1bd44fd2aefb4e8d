"""The `orthogonal` teacher's posture targets: arms raised on Humanoid, a bent knee on Hopper."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from engine.envs import env_model
from engine.errors import InputError
from engine.postures import KNEE_TARGET, orthogonal_score
from engine.teachers import make_teacher
from tests.support.candidates import make_candidates


def _joint(model: mujoco.MjModel, name: str) -> int:
    return int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)])


def _humanoid_arms(shoulder1: float, shoulder2: float, torso_quat=(1, 0, 0, 0)) -> np.ndarray:
    """Humanoid's initial pose with both arms set (mirrored) and the torso turned."""
    model = env_model("Humanoid-v5")
    qpos = model.qpos0.copy()
    qpos[3:7] = torso_quat
    qpos[_joint(model, "right_shoulder1")], qpos[_joint(model, "right_shoulder2")] = (
        -shoulder1,
        -shoulder2,
    )
    qpos[_joint(model, "left_shoulder1")], qpos[_joint(model, "left_shoulder2")] = (
        shoulder1,
        shoulder2,
    )
    return qpos


def test_humanoid_prefers_raised_arms_in_the_torsos_frame() -> None:
    model = env_model("Humanoid-v5")
    lying = (np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0)  # turned 90 degrees about x
    raised, rest, lowered = _humanoid_arms(1.4, 0.35), model.qpos0, _humanoid_arms(-0.9, 1.3)
    scores = orthogonal_score(np.stack([raised, rest, lowered]), model)
    assert scores[0] > 0.9 > scores[1] > scores[2] >= 0.0
    # The same raised arms on a body lying on its side score the same: posture, not height.
    on_its_side = orthogonal_score(_humanoid_arms(1.4, 0.35, lying), model)
    assert on_its_side[0] == pytest.approx(scores[0], abs=1e-6)


@pytest.mark.parametrize(("knee", "expected"), [(KNEE_TARGET, 1.0), (0.0, 0.105), (-2.0, 0.0)])
def test_hopper_prefers_a_bent_knee(knee: float, expected: float) -> None:
    model = env_model("Hopper-v5")
    qpos = model.qpos0.copy()
    qpos[_joint(model, "leg_joint")] = knee
    assert orthogonal_score(qpos, model)[0] == pytest.approx(expected, abs=0.01)


def test_the_teacher_judges_by_its_score() -> None:
    model = env_model("Hopper-v5")
    a, b = make_candidates(2)
    a.qpos[:] = b.qpos[:] = model.qpos0[: len(a.qpos)]
    a.qpos[_joint(model, "leg_joint")], b.qpos[_joint(model, "leg_joint")] = KNEE_TARGET, 0.0
    judge, scores = make_teacher("orthogonal", [a, b], model, rng=np.random.default_rng(0))
    assert judge(a, b) == judge(b, a) == a.id
    assert scores is not None and scores[a.id] > scores[b.id]


def test_an_env_without_a_target_is_refused() -> None:
    with pytest.raises(InputError, match="Humanoid .*Hopper"):
        orthogonal_score(np.zeros((1, 9)), env_model("HalfCheetah-v5"))
