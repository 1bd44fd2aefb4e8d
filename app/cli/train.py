"""``acv train``, ``acv agent-tree`` and ``acv plot``: training with advice from the CLI."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from tqdm import tqdm

from app.cli.root import cli, fail
from engine.envs import DEFAULT_ENV_ID
from engine.judges import DEFAULT_JUDGE, JUDGES, LEGACY_JUDGES
from engine.rl.config import ALGOS, TrainConfig
from engine.treefile import TreeDocument, dump_tree, load_tree

# torch, TensorBoard and matplotlib load inside the commands: `acv` starts fast for the others.

Opt = typer.Option


@cli.command()
def train(
    out: Annotated[Path, Opt(help="Run directory (config, metrics, checkpoints).")],
    advice: Annotated[
        list[Path] | None,
        Opt(
            help="Human Preference Tree (acv.tree/1); give it "
            "more than once to pool several people's "
            "trees over one bracket (F is the mean)."
        ),
    ] = None,
    pool_weight: Annotated[
        list[float] | None,
        Opt(
            help="With several --advice trees: one weight per tree, in the same order (F and "
            "the pooled verdict are then the weighted mean, e.g. each person's reliability); "
            "default: the plain mean."
        ),
    ] = None,
    algo: Annotated[str | None, Opt(help=f"{', '.join(ALGOS)} (default ppo).")] = None,
    timesteps: Annotated[int | None, Opt(help="Env steps in total (default 1000000).")] = None,
    seed: Annotated[int | None, Opt(help="Seed (default 0).")] = None,
    env: Annotated[
        str | None, Opt(help=f"Env id (default: the advice tree's, else {DEFAULT_ENV_ID}).")
    ] = None,
    n_envs: Annotated[int | None, Opt(help="Parallel envs (default 4).")] = None,
    num_steps: Annotated[int | None, Opt(help="Steps per env per rollout (default 512).")] = None,
    checkpoint_every: Annotated[
        int | None, Opt(help="Checkpoint period in env steps (default 50000).")
    ] = None,
    advice_scale: Annotated[float | None, Opt(help="Multiplies F (default 1).")] = None,
    advice_mode: Annotated[
        str | None,
        Opt(
            help="F mode: nearest, softmax, paper-min, or reward "
            "(F = R, the paper's Case 1; --advice is then "
            "the tree to compare against)."
        ),
    ] = None,
    advice_depth_factor: Annotated[
        str | None, Opt(help="Depth factor of F: none or paper.")
    ] = None,
    resume: Annotated[
        bool, Opt(help="Continue the run in --out from its last checkpoint.")
    ] = False,
) -> None:
    """Train PPO or BiPaRS with advice; a progress bar shows steps/s and recent return."""
    given = {
        "algo": algo,
        "total_timesteps": timesteps,
        "seed": seed,
        "env_id": env,
        "n_envs": n_envs,
        "num_steps": num_steps,
        "checkpoint_every": checkpoint_every,
        "advice_scale": advice_scale,
        "advice_mode": advice_mode,
        "advice_depth_factor": advice_depth_factor,
        "pool_weights": tuple(pool_weight) if pool_weight else None,
    }
    _train(out, {k: v for k, v in given.items() if v is not None}, advice or [], resume=resume)


def _train(out: Path, given: dict[str, Any], advice: list[Path], *, resume: bool) -> None:
    """Train (or resume) the run in ``out`` with the options ``given``."""
    from engine.rl.runner import train as train_run

    docs = [load_tree(path) for path in advice]
    doc = docs[0] if docs else None
    config = _resumed_config(out, given) if resume else _new_config(given, doc)
    bars: list[tqdm] = []  # opened at the first update, so input errors print no bar
    try:
        last = train_run(
            config,
            docs if len(docs) > 1 else doc,
            out,
            progress=lambda row: _show(bars, config, row),
            resume=resume,
        )
    finally:
        for bar in bars:
            bar.close()
    typer.echo(f"wrote {out}: last checkpoint {last}")


def _new_config(given: dict[str, Any], doc: TreeDocument | None) -> TrainConfig:
    if "env_id" not in given:
        given["env_id"] = doc.env_id if doc is not None else DEFAULT_ENV_ID
    return TrainConfig(**given)


def _resumed_config(out: Path, given: dict[str, Any]) -> TrainConfig:
    from engine.rl.runner import load_run_config

    config = load_run_config(out)
    clash = {k: v for k, v in given.items() if getattr(config, k) != v}
    if clash:
        fail(
            f"--resume continues {out} as configured; these options differ: "
            + ", ".join(f"{k}={v!r} (run has {getattr(config, k)!r})" for k, v in clash.items())
        )
    return config


def _show(bars: list[tqdm], config: TrainConfig, row: dict[str, Any]) -> None:
    """Advance the bar to the row's timesteps and show speed, recent return and z."""
    if not bars:
        bars.append(
            tqdm(
                total=config.num_updates * config.batch_size,
                unit="step",
                dynamic_ncols=True,
                initial=row["timesteps"] - config.batch_size,
            )
        )
    bar = bars[0]
    bar.update(row["timesteps"] - bar.n)
    ret = row.get("return_100")
    bar.set_postfix(
        sps=f"{row['sps']:.0f}",
        ret="-" if ret is None else f"{ret:.1f}",
        z=f"{row['z_mean']:.2f}",
        refresh=False,
    )


@cli.command(name="agent-tree")
def agent_tree_cmd(
    run: Annotated[Path, Opt(help="Training run directory.")],
    out: Annotated[Path, Opt(help="Where to write the Agent Preference Tree (acv.tree/1).")],
    checkpoint: Annotated[int | None, Opt(help="Checkpoint timesteps (default: the last).")] = None,
    judge: Annotated[str, Opt(help=f"Agent judge: {', '.join(JUDGES)}.")] = DEFAULT_JUDGE,
    advice: Annotated[
        Path | None, Opt(help="Tree whose bracket to replay (default: the run's advice.json).")
    ] = None,
    episodes: Annotated[
        int, Opt(help="behaviour judge: episodes of the deterministic policy at most.")
    ] = 10,
    max_steps: Annotated[int, Opt(help="behaviour judge: env steps at most.")] = 5000,
    rollout_seed: Annotated[int, Opt(help="behaviour judge: seed of the first reset.")] = 0,
    burn_in: Annotated[
        int, Opt(help="behaviour judge: steps after each reset whose states are dropped.")
    ] = 50,
    return_rollouts: Annotated[int, Opt(help="return judge: rollouts per candidate (>= 5).")] = 5,
    horizon: Annotated[int, Opt(help="return judge: env steps per rollout at most.")] = 100,
) -> None:
    """Replay the advice tree's bracket judged by the agent; `acv compare` reads the result.

    Judges: return (the env return its policy earns from each state) and behaviour (a
    revealed-preference tree: which candidates its own rollouts stay near), neither of which
    passed the validation on known answers; diagnostics, "is your advice still in its
    reward?": shaped (R + z F), shaping (z F) and shaped-value (the shaped critic V; formerly
    value)."""
    from engine.rl.agent_judge import agent_tree
    from engine.rl.behaviour import RolloutOptions
    from engine.rl.returns import ReturnOptions

    if LEGACY_JUDGES.get(judge, judge) not in JUDGES:
        fail(f"unknown judge {judge!r}: expected one of {', '.join(JUDGES)}")
    rollouts = RolloutOptions(episodes, max_steps, rollout_seed, burn_in)
    doc = agent_tree(
        run,
        checkpoint,
        judge,
        load_tree(advice) if advice is not None else None,
        rollouts=rollouts,
        returns=ReturnOptions(rollouts=return_rollouts, horizon=horizon),
    )
    dump_tree(doc, out)
    typer.echo(f"wrote {out}: judge {doc.judge}, champion {doc.tree.root}")


@cli.command()
def plot(
    runs: Annotated[list[Path], Opt(help="Run directory, or a folder of seed runs: one curve.")],
    more: Annotated[
        list[Path] | None,
        typer.Argument(help="More curves: `--runs a b c` lists three runs.", show_default=False),
    ] = None,
    out: Annotated[Path, Opt(help="Image file to write (PNG).")] = Path("curves.png"),
    label: Annotated[list[str] | None, Opt(help="Curve label per run, in order.")] = None,
    title: Annotated[str | None, Opt(help="Plot title.")] = None,
) -> None:
    """Learning curves: true episodic return against timesteps, shaded over seeds."""
    from engine.rl.plot import plot_runs

    plot_runs([*runs, *(more or [])], out, label or None, title)
    typer.echo(f"wrote {out}")
