"""SB3 with ACV's advice wrapper next to ACV's own arms (issue 44): the same tree, λ = 10.

Four arms on Hopper-v5, every one with ACV's settings for Hopper (validation round 2's:
500k steps, 4 envs x 512 steps, minibatches of 64, 10 epochs, learning rate annealed to 0,
2x64 tanh networks, observations and rewards normalised; docs/validation.md §2, §6.3):

- ``sb3``: Stable-Baselines3 PPO, no advice;
- ``sb3-advice``: the same, each env wrapped in :class:`engine.rl.shaping.AdviceWrapper`
  (scale 10, offset +1, as ACV's advised arms), inside ``DummyVecEnv`` and ``VecNormalize``;
- ``acv-ppo`` and ``acv-ppo-shaped`` (advice scale 10, offset +1): ACV's arms ``n1`` and
  ``p1-10``, trained by :func:`engine.rl.runner.train`.

**The tree.** No Hopper tree is committed (only Humanoid brackets are, under
``docs/validation/``), so it is made as validation round 2 makes its Hopper bracket 0
(:mod:`engine.validation.round2_runs`): two no-advice ACV pilots (seeds 2000 and 2001, not
evaluation seeds), 16 candidates sampled in the ``informative`` mode from pilot 2000's
deterministic policy, and the ``orthogonal`` teacher's tree over them (a bent knee; BM
seeding, p = 0.9), every draw from seed 30000 (:func:`engine.validation.runs.pilot_bracket`).
The teacher's scores are stripped, as from a person's tree, and every advised arm trains on
that (``OUT/advice.json``; its SHA-256 is in the result). ``--tree FILE`` takes another
``acv.tree/1`` file instead (e.g. a round-2 folder's ``brackets/advice-b0.json``); the pilots
are trained all the same, since they pick the contested matches.

**Judging.** Each SB3 policy is saved, converted to ONNX as ACV's import converts it
(:func:`engine.policies.sb3.sb3_to_onnx`), read back through the upload gate
(:func:`engine.policies.onnx_check.check_onnx`) with its observation normaliser, and scored
on the tree's candidates by :func:`engine.policies.judging.imported_scores` (onnxruntime in a
limited child), as an external experiment's upload is. ACV's runs are scored natively at their
last checkpoint (:func:`engine.rl.agent_judge.agent_tree`, as
:func:`engine.verdict_runs.judge_scores` does). Both verdict judges are used,
``behaviour`` (the primary, docs/validation.md §6.2) and ``return``; the pilots pick the
contested matches for both pairs and give the judges' R (as in ``acv validate``), so the two
pairs' Δ are over the same matches. A pair's verdict is
:func:`engine.verdict_outcome.verdict` (seeded bootstrap).

Each finished run writes ``OUT/results/<arm>-<seed>.json`` (its scores under both judges and
the mean true env return of its last 100 training episodes, R without the advice); a second
call with the same ``--out`` skips those runs (and resumes ACV runs from their checkpoints;
an SB3 run stopped before its result trains again), and may add seeds. Another budget or tree
in the same folder is refused (``OUT/sb3_advice.json`` holds them).

    .venv/bin/python benchmarks/sb3_advice.py --out /work/runs/sb3-advice \
        [--seeds 0 1 2 3 4] [--timesteps 500000] [--jobs 1] [--tree FILE]

It prints, per pair (SB3 with vs without the wrapper; ACV ``ppo-shaped`` vs ``ppo``), the
primary's verdict (outcome, Δ, its 95% interval, p) and each arm's env return mean ± sd, and
as its last line one JSON object with all of it (both judges' verdicts). Ratios and verdicts
only: timings are not part of the result.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from engine.judges import VERDICT_JUDGES
from engine.pinned import pin_settings
from engine.rl.config import TrainConfig
from engine.rl.shaping import AdviceWrapper
from engine.treefile import TreeDocument, dump_tree, load_tree
from engine.validation import round2
from engine.validation.design import ARM_BY_NAME, PILOT
from engine.validation.round2_runs import Round2Plan
from engine.validation.runs import ADVICE_OFFSET, finished, pilot_bracket, run_dir, train_config
from engine.validation.workers import Task, Workers

ENV_ID = "Hopper-v5"
SCALE = 10.0
#: Round 2's Hopper budget (docs/validation.md §6.3).
TIMESTEPS = 500_000
PRIMARY = "behaviour"
JUDGES = (PRIMARY, *(j for j in VERDICT_JUDGES if j != PRIMARY))
PILOT_SEEDS = (round2.PILOT_SEED0, round2.PILOT_SEED0 + 1)
#: The ACV arms, by the validation arm whose settings they train with.
ACV_ARMS = {"acv-ppo": "n1", "acv-ppo-shaped": "p1-10"}
SB3_ARMS = ("sb3", "sb3-advice")
ARMS = (*SB3_ARMS, *ACV_ARMS)
#: (advised, baseline, what it compares) per pair.
PAIRS = (
    ("sb3-advice", "sb3", "SB3 PPO with the AdviceWrapper vs without"),
    ("acv-ppo-shaped", "acv-ppo", "ACV ppo-shaped vs ppo"),
)
VERDICT_SEED = 0
SETTINGS_FILE = "sb3_advice.json"


@dataclass(frozen=True)
class Bench:
    """What every run trains with: the budget, ACV's rollout shape, the judges' rollouts.

    ``n_envs`` and ``num_steps`` are ACV's (4 x 512) but for the fast test; ``episodes`` and
    ``max_steps`` are the behaviour judge's rollouts (10 episodes, 5000 steps) and ``horizon``
    the return judge's (100 steps), the judges' defaults but for the fast test.
    """

    out: Path
    timesteps: int = TIMESTEPS
    n_envs: int = 4
    num_steps: int = 512
    tree: str | None = None
    episodes: int = 10
    max_steps: int = 5000
    horizon: int = 100

    @property
    def plan(self) -> Round2Plan:
        """Round 2's plan for Hopper at this budget: its bracket and training settings."""
        return Round2Plan(
            env_id=ENV_ID, timesteps=self.timesteps, n_envs=self.n_envs, num_steps=self.num_steps
        )

    def config(self, arm: str, seed: int) -> TrainConfig:
        """ACV's settings for ``arm`` (an SB3 arm takes its no-advice twin's) at ``seed``."""
        name = ACV_ARMS.get(arm, "n1" if arm in (*SB3_ARMS, PILOT.name) else arm)
        return train_config(self.plan, ARM_BY_NAME[name], seed)

    def result_path(self, task: Task) -> Path:
        return self.out / "results" / f"{task[0]}-{task[1]}.json"


def advice_path(bench: Bench) -> Path:
    return bench.out / "advice.json"


def make_tree(bench: Bench) -> TreeDocument:
    """The tree every advised arm trains on (module docstring), written once to
    ``OUT/advice.json`` (the teacher's, with its scores, to ``OUT/teacher-tree.json``)."""
    path = advice_path(bench)
    if not path.is_file():
        if bench.tree is not None:
            teacher = load_tree(bench.tree)
        else:
            pilot = run_dir(bench.out, PILOT.name, PILOT_SEEDS[0])
            teacher = pilot_bracket(pilot, bench.plan, round2.BRACKET_SEED0)
        dump_tree(teacher, bench.out / "teacher-tree.json")
        dump_tree(replace(teacher, scores=None), path)
    return load_tree(path)


def _write(path: Path, found: dict[str, Any]) -> dict[str, Any]:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(found) + "\n")
    tmp.replace(path)
    return found


def train_acv(bench: Bench, task: Task, advice: TreeDocument | None) -> Path:
    """Train (or resume) an ACV run into ``OUT/runs/<arm>-<seed>``, as round 2 does."""
    import shutil

    from engine.rl.checkpoint import list_checkpoints
    from engine.rl.runner import train

    folder = run_dir(bench.out, *task)
    if not finished(bench.out, bench.plan, task):
        resume = folder.is_dir() and bool(list_checkpoints(folder))
        if folder.is_dir() and not resume:  # stopped before its first checkpoint
            shutil.rmtree(folder)
        train(bench.config(*task), advice, folder, resume=resume)
    return folder


def _rollouts(bench: Bench) -> dict[str, Any]:
    """The judges' rollouts, the same for SB3's policies and ACV's runs."""
    from engine.rl.behaviour import RolloutOptions
    from engine.rl.returns import ReturnOptions

    return {
        "rollouts": RolloutOptions(episodes=bench.episodes, max_steps=bench.max_steps),
        "returns": ReturnOptions(horizon=bench.horizon),
    }


def acv_result(bench: Bench, task: Task, advice: TreeDocument) -> dict[str, Any]:
    """An ACV run (a pilot or an arm), trained and scored natively at its last checkpoint."""
    from engine.rl.agent_judge import agent_tree, candidate_terms
    from engine.rl.checkpoint import find_checkpoint
    from engine.rl.logger import read_metrics
    from engine.rl.trained import load_agent

    uses_advice = bench.config(*task).uses_advice
    folder = train_acv(bench, task, advice if uses_advice else None)
    last = read_metrics(folder)[-1]
    scores = {}
    for judge in JUDGES:  # engine.verdict_runs.judge_scores, with the return judge's options
        found = agent_tree(folder, None, judge, advice, **_rollouts(bench)).scores
        assert found is not None  # agent_tree records them
        scores[judge] = [found[c.id] for c in advice.candidates]
    reward = candidate_terms(load_agent(find_checkpoint(folder)), advice).reward
    return {
        "arm": task[0],
        "seed": task[1],
        "learner": "acv",
        "algo": bench.config(*task).algo,
        "timesteps": int(last["timesteps"]),
        "env_return": float(last["return_100"]),
        "scores": scores,
        "reward": np.asarray(reward).tolist(),
    }


def sb3_model(bench: Bench, task: Task, advice: TreeDocument | None) -> tuple[Any, Any]:
    """SB3 PPO with ACV's settings (``benchmarks/learning.py``'s), trained on ``n_envs``
    Hopper-v5 envs, each wrapped in :class:`AdviceWrapper` when ``advice`` is given. SB3's
    ``Monitor`` sits inside the wrapper, so its episode returns are the env's R."""
    import torch
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    from engine.envs import make_env
    from engine.rl.sb3_peer import normalised, sb3_ppo

    cfg = bench.config(*task)
    torch.set_num_threads(1)

    def one_env() -> Any:
        env = Monitor(make_env(ENV_ID))
        if advice is None:
            return env
        return AdviceWrapper(env, advice, scale=SCALE, offset=ADVICE_OFFSET)

    venv = normalised(DummyVecEnv([one_env] * cfg.n_envs), cfg)
    model = sb3_ppo(cfg, venv)
    model.learn(total_timesteps=cfg.num_updates * cfg.batch_size)  # whole rollouts, as ACV
    return model, venv


def sb3_policy(model: Any, venv: Any, folder: Path) -> Any:
    """The save (``ppo.zip``), its normaliser (``obs_norm.npz``), converted to ONNX as ACV's
    import does (``policy.onnx``) and read back through the upload gate."""
    from stable_baselines3.common.running_mean_std import RunningMeanStd

    from engine.envs import env_dims
    from engine.policies.normalisation import ObsNormalisation
    from engine.policies.onnx_check import check_onnx
    from engine.policies.onnx_policy import ImportedPolicy
    from engine.policies.sb3 import sb3_to_onnx

    folder.mkdir(parents=True, exist_ok=True)
    zip_path, npz_path, onnx_path = (
        folder / "ppo.zip",
        folder / "obs_norm.npz",
        folder / "policy.onnx",
    )
    model.save(zip_path)
    rms = venv.obs_rms
    assert isinstance(rms, RunningMeanStd)
    np.savez(npz_path, mean=rms.mean, var=rms.var, clip=venv.clip_obs, epsilon=venv.epsilon)
    converted = sb3_to_onnx(zip_path.read_bytes(), env_id=ENV_ID, activation="tanh")
    onnx_path.write_bytes(converted.model.data)
    obs_dim, act_dim = env_dims(ENV_ID)
    checked = check_onnx(onnx_path.read_bytes(), env_id=ENV_ID, obs_dim=obs_dim, act_dim=act_dim)
    norm = ObsNormalisation.from_npz(npz_path.read_bytes(), obs_dim=obs_dim)
    return ImportedPolicy(checked, norm)


def sb3_result(bench: Bench, task: Task, advice: TreeDocument) -> dict[str, Any]:
    """An SB3 run: trained, exported to ONNX and judged as an imported policy."""
    from engine.policies.judging import imported_scores

    arm, seed = task
    model, venv = sb3_model(bench, task, advice if arm == "sb3-advice" else None)
    folder = run_dir(bench.out, *task)
    policy = sb3_policy(model, venv, folder)
    scores = {}
    for judge in JUDGES:
        found = imported_scores(policy, advice, judge, cache_dir=folder, **_rollouts(bench))
        scores[judge] = [found[c.id] for c in advice.candidates]
    episodes = [info["r"] for info in model.ep_info_buffer]
    return {
        "arm": arm,
        "seed": seed,
        "learner": "sb3",
        "algo": "sb3 PPO" + (f" + AdviceWrapper(scale={SCALE:g})" if arm == "sb3-advice" else ""),
        "timesteps": int(model.num_timesteps),
        "env_return": float(np.mean(episodes)) if episodes else None,
        "scores": scores,
        "onnx_sha256": policy.model.digest,
    }


def run_task(bench: Bench, task: Task) -> dict[str, Any]:
    """One run, trained and scored once: ``OUT/results/<arm>-<seed>.json`` (read back when
    it exists)."""
    path = bench.result_path(task)
    if path.is_file():
        found: dict[str, Any] = json.loads(path.read_text())
        return found
    advice = load_tree(advice_path(bench)) if task[0] != PILOT.name else None
    if task[0] == PILOT.name:  # trained before the tree exists; scored once it does
        train_acv(bench, task, None)
        return {}
    assert advice is not None
    work = sb3_result if task[0] in SB3_ARMS else acv_result
    return _write(path, work(bench, task, advice))


def pilot_result(bench: Bench, seed: int) -> dict[str, Any]:
    path = bench.result_path((PILOT.name, seed))
    if path.is_file():
        found: dict[str, Any] = json.loads(path.read_text())
        return found
    return _write(path, acv_result(bench, (PILOT.name, seed), load_tree(advice_path(bench))))


def pair_verdicts(
    advice: TreeDocument, results: dict[Task, dict[str, Any]], seeds: list[int]
) -> list[dict[str, Any]]:
    """Each pair's verdict under each judge, and each arm's env return."""
    from engine.verdict import VerdictInputs, advice_scores, bracket_pairs
    from engine.verdict_outcome import verdict

    pilots = [results[(PILOT.name, s)] for s in PILOT_SEEDS]
    reward = np.mean([p["reward"] for p in pilots], axis=0)
    out = []
    for advised, baseline, what in PAIRS:
        judged = {}
        for judge in JUDGES:
            scores = {
                arm: np.array([results[(arm, s)]["scores"][judge] for s in seeds])
                for arm in (advised, baseline)
            }
            pilot = np.array([p["scores"][judge] for p in pilots])
            inputs = VerdictInputs(
                advice_scores(advice),
                scores[advised],
                scores[baseline],
                pilot,
                bracket_pairs(advice),
                reward,
            )
            found = verdict(inputs, np.random.default_rng(VERDICT_SEED)).to_json()
            judged[judge] = {
                k: found[k]
                for k in ("outcome", "label", "delta", "interval", "p_value", "auc", "reason")
            } | {"n_contested": found["n_contested"]}
        returns = {
            arm: _spread([results[(arm, s)]["env_return"] for s in seeds])
            for arm in (advised, baseline)
        }
        out.append(
            {
                "pair": what,
                "advised": advised,
                "baseline": baseline,
                "verdict": judged,
                "env_return": returns,
            }
        )
    return out


def _spread(values: list[float | None]) -> dict[str, Any]:
    x = np.array([np.nan if v is None else v for v in values], dtype=float)
    sd = float(np.std(x, ddof=1)) if len(x) > 1 else None
    return {"mean": float(np.mean(x)), "sd": sd, "per_seed": x.tolist()}


def run(bench: Bench, seeds: list[int], jobs: int = 1) -> dict[str, Any]:
    """Pilots, the tree, every arm at every seed (``jobs`` at a time), then the verdicts."""
    # another budget or tree in the same folder is refused: its results would not compare
    settings = {k: getattr(bench, k) for k in ("timesteps", "n_envs", "num_steps", "tree")}
    pin_settings(bench.out / SETTINGS_FILE, settings, "an SB3 advice benchmark", lambda s: s)
    workers = Workers(jobs=jobs)
    pilots = [(PILOT.name, s) for s in PILOT_SEEDS]
    workers.map(partial(run_task, bench), [t for t in pilots if not bench.result_path(t).is_file()])
    advice = make_tree(bench)
    tasks = [(arm, s) for s in seeds for arm in ARMS]
    found = workers.map(partial(run_task, bench), tasks)
    results = dict(zip(tasks, found, strict=True))
    results |= {(PILOT.name, s): pilot_result(bench, s) for s in PILOT_SEEDS}
    tree_sha = hashlib.sha256(advice_path(bench).read_bytes()).hexdigest()
    return {
        "env_id": ENV_ID,
        "advice_scale": SCALE,
        "advice_offset": ADVICE_OFFSET,
        "timesteps": bench.timesteps,
        "n_envs": bench.n_envs,
        "num_steps": bench.num_steps,
        "seeds": seeds,
        "pilot_seeds": list(PILOT_SEEDS),
        "tree": str(advice_path(bench)),
        "tree_sha256": tree_sha,
        "tree_source": bench.tree
        or f"orthogonal teacher, pilot {PILOT_SEEDS[0]}, seed {round2.BRACKET_SEED0}",
        "primary": PRIMARY,
        "pairs": pair_verdicts(advice, results, seeds),
    }


def _number(x: float | None, digits: int = 3) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def report(summary: dict[str, Any]) -> str:
    """The lines printed per pair: the primary's verdict and each arm's env return."""
    lines = []
    for pair in summary["pairs"]:
        v = pair["verdict"][summary["primary"]]
        interval = v["interval"] and f"[{_number(v['interval'][0])}, {_number(v['interval'][1])}]"
        lines.append(
            f"{pair['pair']} ({summary['primary']}): {v['outcome']}, Δ = {_number(v['delta'])} "
            f"{interval or '[-]'}, p = {_number(v['p_value'])}"
            + (f" ({v['reason']})" if v["reason"] else "")
        )
        for arm, r in pair["env_return"].items():
            lines.append(f"  {arm}: env return {r['mean']:.1f} ± {_number(r['sd'], 1)}")
    return "\n".join(lines)


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="runs and results (resumable)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--timesteps", type=int, default=TIMESTEPS)
    parser.add_argument("--jobs", type=int, default=1, help="runs trained at a time")
    parser.add_argument("--tree", default=None, help="an acv.tree/1 file (default: module doc)")
    parser.add_argument("--n-envs", type=int, default=4, help="ACV's 4; less for a smoke test")
    parser.add_argument("--num-steps", type=int, default=512, help="ACV's 512 steps per env")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    args = parse(argv)
    bench = Bench(
        out=args.out,
        timesteps=args.timesteps,
        n_envs=args.n_envs,
        num_steps=args.num_steps,
        tree=args.tree,
    )
    summary = run(bench, args.seeds, args.jobs)
    print(report(summary))
    print(json.dumps(summary), flush=True)
    return summary


if __name__ == "__main__":
    main()
