"""The advice as a public Gymnasium wrapper (issue 44 §1, §3): its shaped reward, ``info["R"]``
and ``info["F"]`` equal ACV's own training path on the same seeded envs, inside Gymnasium's
vector env and SB3's; trees load from every place ACV hands them out.

R is equal bit for bit. F, and so the shaped reward, to the last bit or two only: the training
path scores a batch of reached states in one matrix product and the wrapper one state, and
BLAS rounds a row of a product differently with the batch's size (seen: 38.84801865208939
against ...938). A batch-invariant product would make them equal, but it changes the training
path's last bits, a number-altering change that waits until validation round 2 is trained
(docs/validation.md §6; tests/engine/rl/test_bit_identity.py)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

from engine.advice import AdviceReward
from engine.envs import make_env
from engine.errors import InputError
from engine.rl.shaping import AdviceWrapper, advice_tree
from engine.rl.vecenv import make_vec_env
from engine.treefile import load_tree, tree_to_json

#: A committed 16-candidate Humanoid-v5 bracket (the bit-identity tests' advice).
TREE = Path(__file__).parent / "data" / "bit_identity" / "advice.json"
ENV, N_ENVS, STEPS, SCALE, OFFSET = "Humanoid-v5", 3, 120, 10.0, 1.0


def _wrapped() -> gym.Env[Any, Any]:
    return AdviceWrapper(make_env(ENV), TREE, scale=SCALE, offset=OFFSET)


def test_the_wrapper_equals_the_training_path_bit_for_bit() -> None:
    """Same seeds, same actions; random Humanoid actions fall within ~25 steps, so the
    comparison crosses several autoresets (the reached state of a finished episode)."""
    ours = make_vec_env(ENV, N_ENVS, AdviceReward.from_tree(load_tree(TREE)), SCALE, OFFSET)
    theirs = gym.vector.SyncVectorEnv(
        [_wrapped] * N_ENVS, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP
    )
    seeds = list(range(N_ENVS))
    ours.reset(seed=seeds), theirs.reset(seed=seeds)
    rng, done_steps = np.random.default_rng(0), 0
    for _ in range(STEPS):
        actions = rng.uniform(-0.4, 0.4, (N_ENVS, *ours.single_action_space.shape))
        _, _, _, _, info = ours.step(actions)
        _, shaped, terminated, truncated, found = theirs.step(actions)
        done = terminated | truncated
        done_steps += int(done.sum())
        r, f = _per_env(found, "R", done), _per_env(found, "F", done)
        assert r.tolist() == info["env_reward"].tolist()
        np.testing.assert_allclose(f, info["advice"], rtol=1e-14, atol=0)
        assert shaped.tolist() == (r + f).tolist()  # R + scale (F + offset), z = 1
    assert done_steps >= 5


def _per_env(info: dict[str, Any], key: str, done: np.ndarray) -> np.ndarray:
    """A step's value per env: a finished env's sits in ``final_info`` (same-step reset)."""
    values = np.array(info[key], dtype=np.float64) if key in info else np.zeros(len(done))
    if done.any():
        values[done] = np.asarray(info["final_info"][key], dtype=np.float64)[done]
    return values


def test_inside_sb3s_vec_env() -> None:
    vec = DummyVecEnv([_wrapped, _wrapped])
    vec.seed(0)
    vec.reset()
    _, rewards, _, infos = vec.step(np.zeros((2, *vec.action_space.shape)))
    for reward, info in zip(rewards, infos, strict=True):
        assert np.float32(info["R"] + info["F"]) == reward  # SB3 keeps rewards as float32
        assert info["F"] >= 0.0  # offset 1: F + 1 >= 0


@pytest.mark.parametrize("kind", ["path", "text", "mapping", "document"])
def test_trees_load_from_every_form_acv_hands_out(kind: str) -> None:
    doc = load_tree(TREE)
    text = json.dumps(tree_to_json(doc))
    source = {"path": TREE, "text": text, "mapping": json.loads(text), "document": doc}[kind]
    assert advice_tree(source).results == doc.results


@pytest.mark.parametrize(
    ("source", "message"),
    [("{not json", "invalid JSON"), ({"schema": "other"}, "not an acv.tree/1 document")],
)
def test_a_bad_tree_is_refused(source: Any, message: str) -> None:
    with pytest.raises(InputError, match=message):
        advice_tree(source)


def test_a_tree_for_another_env_is_refused() -> None:
    with pytest.raises(InputError, match="the tree is for Humanoid-v5, the env is Hopper-v5"):
        AdviceWrapper(make_env("Hopper-v5"), TREE)
