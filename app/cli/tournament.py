"""``acv tournament``, ``acv compare`` and ``acv demo``: the engine from the command line."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, cast

import typer
from rich.console import Console
from rich.table import Table

from app.cli.options import (
    CandidatesOpt,
    CoinOpt,
    EnvOpt,
    JsonOpt,
    NoiseOpt,
    SamplingOpt,
    TeacherOpt,
)
from app.cli.root import cli, fail
from engine.candidates import BASELINE_MODES, SAMPLING_MODES, Policy, SamplingMode
from engine.conformance import Conformance, compare
from engine.envs import DEFAULT_ENV_ID, check_env_id
from engine.errors import check_seed
from engine.pipeline import replay_with_teacher, run_tournament
from engine.teachers import TEACHERS
from engine.treefile import TreeDocument, dump_tree, load_tree


@cli.command()
def tournament(
    out: Annotated[Path, typer.Option(help="Where to write the acv.tree/1 document.")],
    env: EnvOpt = DEFAULT_ENV_ID,
    candidates: CandidatesOpt = 16,
    p: CoinOpt = 0.9,
    seed: Annotated[int, typer.Option(help="Seed for sampling, seeding and noise.")] = 0,
    teacher: TeacherOpt = "standing",
    noise: NoiseOpt = 0.0,
    sampling: SamplingOpt = "uniform",
    baseline: Annotated[
        Path | None,
        typer.Option(
            help="informative sampling: a finished no-advice ppo run directory (or a "
            "checkpoint file) whose policy the candidates' rollouts follow."
        ),
    ] = None,
    replay: Annotated[
        Path | None,
        typer.Option(help="Replay this tree's bracket (same candidates and first round)."),
    ] = None,
) -> None:
    """Sample candidates, seed a bracket, let a simulated teacher play it, write the tree."""
    if teacher not in TEACHERS:
        fail(f"unknown teacher {teacher!r}: expected one of {', '.join(TEACHERS)}")
    if not 0.0 <= noise <= 1.0:
        fail(f"--noise must be in [0, 1], got {noise}")
    if replay is not None:
        doc = replay_with_teacher(load_tree(replay), teacher, noise)
    else:
        _check_new(env, candidates, p, seed, sampling)
        if (sampling in BASELINE_MODES) != (baseline is not None):
            fail(
                f"--sampling {sampling} needs --baseline, a finished no-advice ppo run on {env}"
                if baseline is None
                else f"--baseline is for --sampling {' or '.join(BASELINE_MODES)} only"
            )
        doc = run_tournament(
            env_id=env,
            n_candidates=candidates,
            p=p,
            seed=seed,
            teacher=teacher,
            noise=noise,
            sampling=cast(SamplingMode, sampling),
            policy=None if baseline is None else _baseline_policy(baseline, env),
        )  # _check_new checked it
    dump_tree(doc, out)
    typer.echo(f"wrote {out}: {len(doc.candidates)} candidates, champion {doc.tree.root}")


def _baseline_policy(path: Path, env: str) -> Policy:
    """The deterministic policy of a no-advice run's last checkpoint (or of a checkpoint)."""
    from engine.rl.checkpoint import find_checkpoint
    from engine.rl.trained import deterministic_policy, load_agent

    trained = load_agent(path if path.is_file() else find_checkpoint(path))
    if trained.config.uses_advice or trained.config.env_id != env:
        fail(
            f"--baseline must be a no-advice ppo run on {env}, got {trained.config.algo} on "
            f"{trained.config.env_id}"
        )
    return deterministic_policy(trained)


def _check_new(env: str, candidates: int, p: float, seed: int, sampling: str) -> None:
    check_seed(seed)
    if candidates < 2:
        fail(f"--candidates must be at least 2, got {candidates}")
    if not 0.0 <= p <= 1.0:
        fail(f"--p must be in [0, 1], got {p}")
    if sampling not in SAMPLING_MODES:
        fail(f"--sampling must be one of {', '.join(SAMPLING_MODES)}, got {sampling!r}")
    check_env_id(env)


@cli.command(name="compare")
def compare_cmd(
    human: Annotated[Path, typer.Argument(help="The Human Preference Tree (acv.tree/1).")],
    agent: Annotated[Path, typer.Argument(help="The other tree, over the same bracket.")],
    as_json: JsonOpt = False,
) -> None:
    """Conformance metrics of the second tree to the first."""
    result = compare(load_tree(human), load_tree(agent))
    if as_json:
        typer.echo(json.dumps(result.to_json(), indent=1))
    else:
        print_conformance(result, load_tree(human), load_tree(agent))


def print_conformance(c: Conformance, human: TreeDocument, agent: TreeDocument) -> None:
    """A readable table of the metrics and the rejected advice."""
    console = Console()
    table = Table(title=f"Conformance of {agent.judge!r} to {human.judge!r}")
    table.add_column("metric")
    table.add_column("value", justify="right")
    table.add_row("contested matches kept", _contested_text(c))
    table.add_row("an R-only judge would agree", f"{c.reference_agreement:.3f}")
    lo, hi = c.match_agreement_ci
    table.add_row(
        "match agreement",
        f"{c.n_agree}/{c.n_matches} = {c.match_agreement:.3f}  (95% CI {lo:.3f}..{hi:.3f})",
    )
    tau = "undefined" if c.kendall_tau_b is None else f"{c.kendall_tau_b:.3f}"
    table.add_row("Kendall tau-b of heights", tau)
    table.add_row("tree edit distance (normalised)", f"{c.tree_edit_distance:.3f}")
    table.add_row(
        "same champion",
        "yes" if c.same_champion else f"no ({human.tree.root} vs {agent.tree.root})",
    )
    console.print(table)
    if c.rejected:
        rej = Table(title="Rejected advice: matches the agent decided the other way")
        for col in ("round", "match", "human preferred", "agent preferred", "contested"):
            rej.add_column(col)
        for r in c.rejected:
            rej.add_row(
                str(r.round),
                f"{r.a} vs {r.b}",
                str(r.human_winner),
                "no preference" if r.agent_winner is None else str(r.agent_winner),
                "yes" if r.contested else "",
            )
        console.print(rej)


def _contested_text(c: Conformance) -> str:
    """``3/5 = 0.600 (95% CI ...)``, or why there is nothing to tell."""
    k = c.contested
    if k.n == 0 or k.agreement_ci is None:  # the interval is None exactly when n == 0
        return "none contested: this bracket cannot tell whether the advice was used"
    lo, hi = k.agreement_ci
    return f"{k.kept}/{k.n} = {k.agreement:.3f}  (95% CI {lo:.3f}..{hi:.3f})"


@cli.command()
def demo(
    env: EnvOpt = DEFAULT_ENV_ID,
    candidates: CandidatesOpt = 16,
    seed: Annotated[int, typer.Option(help="Seed.")] = 0,
) -> None:
    """The engine end to end: a `standing` teacher's tree against its `good` replay."""
    check_env_id(env)
    human = run_tournament(
        env_id=env, n_candidates=candidates, p=0.9, seed=seed, teacher="standing"
    )
    other = replay_with_teacher(human, "good")
    print_conformance(compare(human, other), human, other)
