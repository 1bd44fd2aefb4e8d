"""Train Stable-Baselines3 PPO on Hopper-v5 with a person's advice, then export it to ONNX.

ACV's advice is a Gymnasium wrapper (:class:`engine.rl.shaping.AdviceWrapper`): each step's
reward becomes ``R + scale * (F(s') + offset)``, what ACV's ``ppo-shaped`` arm optimises, with
F from the person's Preference Tree. This example is the whole path of an agent trained
elsewhere:

1. the tree: ``--tree`` (an ``acv.tree/1`` file: a study's ``tree.json`` download, the JSON
   of ``GET /api/participants/{id}/tree``, or ``acv tournament --env Hopper-v5 --out
   tree.json``); without it, a simulated teacher (``standing``) plays a small bracket as a
   stand-in for a person, written to ``OUT/tree.json``;
2. SB3 PPO trains on the wrapped env inside ``DummyVecEnv`` and ``VecNormalize``, with ACV's
   PPO settings (4 envs x 512 steps, minibatches of 64, 10 epochs, a 64-64 tanh MLP,
   observations and rewards normalised; SB3 keeps the learning rate constant where ACV
   anneals it);
3. the policy is saved as SB3 saves it (``OUT/ppo.zip``), and the observation normaliser as
   the ``.npz`` that ACV reads (``OUT/obs_norm.npz``; SB3 pickles ``VecNormalize``, which ACV
   never loads);
4. the save is converted to ONNX the way ACV's import converts it, without unpickling
   (:func:`engine.policies.sb3.sb3_to_onnx`), written to ``OUT/policy.onnx``, and that file is
   read back and checked by the gate every imported policy passes
   (:func:`engine.policies.onnx_check.check_onnx`);
5. onnxruntime runs one episode of the ONNX policy in the advised env, and each action is
   compared with SB3's own deterministic ``predict``.

Usage (needs ``stable-baselines3``, ``onnx`` and ``onnxruntime``; the default budget takes a
few minutes on a CPU)::

    python examples/sb3_hopper_advice.py [--tree TREE] [--timesteps 50000] [--scale 10]
        [--offset 1] [--n-envs 4] [--n-steps 512] [--seed 0] [--out sb3-hopper-advice]
        [--json]

The report (``--json`` prints it as JSON) names the files, the settings the save declares,
the tree file's SHA-256, the episode's R, advice and shaped return, and the largest
difference between the ONNX policy's and SB3's actions.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from engine.envs import env_dims, make_env
from engine.gym_types import box
from engine.pipeline import run_tournament
from engine.policies.normalisation import ObsNormalisation
from engine.policies.onnx_check import ENV_ID_KEY, check_onnx
from engine.policies.onnx_policy import ImportedPolicy, OnnxPolicy
from engine.policies.sb3 import Declared, sb3_to_onnx
from engine.rl.shaping import AdviceWrapper
from engine.treefile import dump_tree

ENV_ID = "Hopper-v5"
#: ACV's minibatch size at its defaults (4 envs x 512 steps / 32 minibatches).
BATCH_SIZE = 64
#: The stand-in teacher's bracket: small, so that it is sampled in a fraction of a second.
STAND_IN_CANDIDATES = 8
Action = Callable[[np.ndarray], np.ndarray]


def tree_file(tree: str | None, out: Path, seed: int) -> Path:
    """The tree to advise with: ``tree`` when given, else a simulated teacher's bracket
    (``standing``, the paper's case 2) written to ``out/tree.json``."""
    if tree is not None:
        return Path(tree)
    doc = run_tournament(
        env_id=ENV_ID, n_candidates=STAND_IN_CANDIDATES, p=0.9, seed=seed, teacher="standing"
    )
    path = out / "tree.json"
    dump_tree(doc, path)
    return path


def advised_env(tree: Path, scale: float, offset: float) -> gym.Env[Any, Any]:
    """One Hopper-v5 whose reward is ``R + scale * (F + offset)`` under the person's tree."""
    return AdviceWrapper(make_env(ENV_ID), tree, scale=scale, offset=offset)


def train(tree: Path, args: argparse.Namespace) -> tuple[PPO, VecNormalize]:
    """SB3 PPO on ``args.n_envs`` advised envs, normalised as ACV normalises its own runs."""
    # One thread, as ACV's runner trains: a 64-64 MLP's ops are too small to split, and a
    # second thread fights the envs for the cores (seen: 10x slower on a busy 2-core box).
    torch.set_num_threads(1)
    venv = VecNormalize(
        DummyVecEnv([lambda: advised_env(tree, args.scale, args.offset)] * args.n_envs)
    )
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=args.n_steps,
        # SB3 wants a minibatch no larger than a rollout: tiny budgets have small rollouts.
        batch_size=min(BATCH_SIZE, args.n_steps * args.n_envs),
        seed=args.seed,
        device="cpu",  # a 64-64 MLP runs faster on a CPU than it waits for a GPU
    )
    model.learn(total_timesteps=args.timesteps)
    return model, venv


def save(model: PPO, venv: VecNormalize, out: Path) -> tuple[Path, Path]:
    """The SB3 save and the normaliser's ``.npz`` (engine/policies/normalisation.py's three
    lines, on the live object instead of a loaded ``vec_normalize.pkl``)."""
    zip_path, npz_path = out / "ppo.zip", out / "obs_norm.npz"
    model.save(zip_path)
    rms = venv.obs_rms
    assert isinstance(rms, RunningMeanStd)  # a dict only for dict observations
    np.savez(npz_path, mean=rms.mean, var=rms.var, clip=venv.clip_obs, epsilon=venv.epsilon)
    return zip_path, npz_path


def to_onnx(zip_path: Path, npz_path: Path, out: Path) -> tuple[ImportedPolicy, Declared]:
    """Convert the save as ACV's import does, write ``out/policy.onnx``, and read both files
    back through the checks an upload passes. Returns the policy and the save's declared
    settings."""
    # PPO's MlpPolicy defaults to tanh; the activation cannot be read without unpickling.
    converted = sb3_to_onnx(zip_path.read_bytes(), env_id=ENV_ID, activation="tanh")
    onnx_path = out / "policy.onnx"
    onnx_path.write_bytes(converted.model.data)
    obs_dim, act_dim = env_dims(ENV_ID)
    checked = check_onnx(onnx_path.read_bytes(), env_id=ENV_ID, obs_dim=obs_dim, act_dim=act_dim)
    norm = ObsNormalisation.from_npz(npz_path.read_bytes(), obs_dim=obs_dim)
    return ImportedPolicy(checked, norm), converted.declared


def sb3_action(model: PPO, venv: VecNormalize) -> Action:
    """SB3's deterministic action for one raw observation: the mean, clipped to the box."""

    def act(obs: np.ndarray) -> np.ndarray:
        action, _ = model.predict(venv.normalize_obs(obs), deterministic=True)
        return np.asarray(action)

    return act


def episode(
    policy: OnnxPolicy, reference: Action, tree: Path, args: argparse.Namespace
) -> dict[str, Any]:
    """One episode of the ONNX policy in the advised env (seeded with ``args.seed``): its
    length, returns, and the largest gap between its actions and ``reference``'s."""
    env = advised_env(tree, args.scale, args.offset)
    space = box(env.action_space)
    obs, _ = env.reset(seed=args.seed)
    rows: list[tuple[float, float, float]] = []  # per step: R, the advice term, the reward
    gap, done = 0.0, False
    try:
        while not done:
            # clipped to the box, as SB3's predict and ACV's judges clip the mean
            action = np.clip(policy(obs), space.low, space.high)
            gap = max(gap, float(np.abs(action - reference(obs)).max()))
            obs, shaped, terminated, truncated, info = env.step(action)
            rows.append((info["R"], info["F"], float(shaped)))
            done = terminated or truncated
    finally:
        env.close()
    r, f, shaped_return = (float(t) for t in np.sum(rows, axis=0))
    return {
        "steps": len(rows),
        "R": r,
        "F": f,
        "shaped": shaped_return,
        "max_action_difference": gap,
    }


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Train, save, convert, check and run once (see the module docstring); the report."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tree = tree_file(args.tree, out, args.seed)
    model, venv = train(tree, args)
    zip_path, npz_path = save(model, venv, out)
    imported, declared = to_onnx(zip_path, npz_path, out)
    played = episode(OnnxPolicy(imported), sb3_action(model, venv), tree, args)
    return {
        "env_id": imported.model.metadata[ENV_ID_KEY],
        "declared": {k: declared.get(k) for k in ("num_timesteps", "seed", "n_envs")},
        "tree": str(tree),
        # an import declares the tree the wrapper used (issue 44 §2): the file's hash names it
        "tree_sha256": hashlib.sha256(tree.read_bytes()).hexdigest(),
        "files": {
            "sb3": str(zip_path),
            "normalisation": str(npz_path),
            "onnx": str(out / "policy.onnx"),
        },
        "onnx_sha256": imported.model.digest,
        "episode": played,
    }


def parse(argv: list[str] | None) -> argparse.Namespace:
    """The command line (the module docstring's usage)."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--tree", help="an acv.tree/1 file (default: a simulated teacher's)")
    parser.add_argument("--timesteps", type=int, default=50_000, help="env steps to train")
    parser.add_argument("--scale", type=float, default=10.0, help="the advice's scale, λ")
    parser.add_argument("--offset", type=float, default=1.0, help="added to F before scale")
    parser.add_argument("--n-envs", type=int, default=4, help="envs in the DummyVecEnv")
    parser.add_argument("--n-steps", type=int, default=512, help="steps per env per rollout")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="sb3-hopper-advice", help="folder for the files")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Run the example with ``argv`` (default: the command line); print and return the report."""
    args = parse(argv)
    report = run(args)
    print(json.dumps(report) if args.json else json.dumps(report, indent=2))
    return report


if __name__ == "__main__":
    main()
