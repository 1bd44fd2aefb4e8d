"""``acv verdict``: advised runs against a matched no-advice baseline (docs/method.md §2.11)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from app.cli.options import JsonOpt
from app.cli.root import cli, fail
from engine.judges import DEFAULT_JUDGE
from engine.treefile import load_tree

Opt = typer.Option


@cli.command(name="verdict")
def verdict_cmd(
    advice: Annotated[Path, Opt(help="The advice tree (acv.tree/1) the runs are judged on.")],
    advised: Annotated[list[Path], Opt(help="An advised run directory; repeat per seed.")],
    baseline: Annotated[
        list[Path], Opt(help="A no-advice run on an evaluation seed; repeat per seed.")
    ],
    pilot: Annotated[
        list[Path],
        Opt(help="A no-advice run on a seed of its own (picks the contested matches); repeat."),
    ],
    judge: Annotated[
        str, Opt(help="The judge that scores every run's candidates (value: shaped-value).")
    ] = DEFAULT_JUDGE,
    margin_advice: Annotated[
        float, Opt(help="Share of the advice scores' range a winner must lead by.")
    ] = 0.05,
    margin_baseline: Annotated[
        float, Opt(help="Share of the pilot scores' range a pilot preference must reach.")
    ] = 0.05,
    seed: Annotated[int, Opt(help="Seed of the bootstrap interval.")] = 0,
    tensorboard: Annotated[
        bool,
        Opt(help="Write the numbers into the advised and baseline runs' TensorBoard logs."),
    ] = True,
    as_json: JsonOpt = False,
) -> None:
    """Did the advised runs keep the advice more than runs without it? Scores each run's last
    checkpoint with the judge, then tests the difference (exact permutation test, α = 0.05).
    The numbers go to TensorBoard too, as ``verdict/<judge>/...`` beside each run's
    hyper-parameters: ``tensorboard --logdir`` the runs' parent folder, tab HPARAMS."""
    from engine.errors import check_seed
    from engine.judges import judge_name
    from engine.rl.hparams import log_verdict
    from engine.verdict import VerdictOptions
    from engine.verdict_runs import runs_verdict

    for name, value in (("--margin-advice", margin_advice), ("--margin-baseline", margin_baseline)):
        if not 0.0 <= value <= 1.0:
            fail(f"{name} must be in [0, 1], got {value}")
    options = VerdictOptions(margin_advice=margin_advice, margin_baseline=margin_baseline)
    result = runs_verdict(
        load_tree(advice),
        (advised, baseline, pilot),
        judge,
        np.random.default_rng(check_seed(seed)),
        options,
    )
    if tensorboard:
        log_verdict(result, judge_name(judge), advised, baseline)
    typer.echo(json.dumps(result.to_json(), indent=1) if as_json else result.text)
