"""The verdict's positive control on Hopper-v5 (issue 25, "Done when"; docs/method.md §2.11).

Advice that the agent cannot ignore: ``ppo-shaped`` with the `orthogonal` teacher's tree (a
bent knee, which R does not pay for) at scale 10, against ``ppo`` with no advice, 4 seeds each,
contested matches picked by 2 pilot ``ppo`` runs on seeds of their own. The verdict must say
"used your advice". The same design trained on a *shuffled* tree (the `random` teacher on the
same bracket, a fair coin per match), still judged against the real advice, must not: a
shaping term of the same size that carries no advice is not "using the advice".

The budget is what the advice needs to change the agent at all. Measured (the teacher's own
knee score over 5 deterministic episodes from reset seeds 10000-10004, seeds 0 and 1): at
61,440 steps the advised agents scored 0.38 and 0.46 against no advice's 0.31 and 0.55, no
change, and this design's verdict was "no different" (shaped-value: Δ = 0.00 [-0.36, 0.39],
p = 1.0); at 245,760 steps 0.92 and 0.50 against 0.70 and 0.29.

The judge is `shaped-value` (the critic, which learns R + zF). The judges that read the
agent's behaviour (`return`, `behaviour`) are recorded, not asserted
(``test_the_behaviour_judges_verdicts``, run with ``-s``): this 16-candidate bracket has few
informative contested matches for them (2 to 5 at 61,440 steps).

Training 14 runs takes about an hour on two free cores. ``ACV_POSITIVE_CONTROL_DIR`` names a
folder to train in and to reuse finished runs from (they are named ``<arm>-<seed>``).
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pytest

from engine.pipeline import replay_with_teacher, run_tournament
from engine.rl.checkpoint import list_checkpoints
from engine.rl.config import TrainConfig
from engine.rl.runner import train
from engine.treefile import TreeDocument, dump_tree, load_tree
from engine.verdict_runs import runs_verdict

pytestmark = [pytest.mark.slow, pytest.mark.training]

ENV = "Hopper-v5"
STEPS = 245_760  # 120 updates of 4 envs x 512 steps
SEEDS = (0, 1, 2, 3)
PILOT_SEEDS = (100, 101)


def _train(algo: str, seed: int, advice_file: Path | None, out: Path) -> Path:
    """One run (in a worker process; torch uses one thread per run), unless it is trained."""
    if out.exists() and STEPS in list_checkpoints(out):
        return out
    config = TrainConfig(
        algo=algo,
        env_id=ENV,
        total_timesteps=STEPS,
        seed=seed,
        advice_scale=10.0,
        checkpoint_every=STEPS,
    )
    train(config, None if advice_file is None else load_tree(advice_file), out)
    return out


@pytest.fixture(scope="module")
def design(tmp_path_factory) -> tuple[TreeDocument, dict[str, list[Path]]]:
    """The advice tree and the run directories of each arm, trained two at a time."""
    named = os.environ.get("ACV_POSITIVE_CONTROL_DIR")
    root = Path(named) if named else tmp_path_factory.mktemp("positive-control")
    root.mkdir(parents=True, exist_ok=True)
    advice = run_tournament(env_id=ENV, n_candidates=16, p=0.9, seed=0, teacher="orthogonal")
    dump_tree(advice, root / "advice.json")
    dump_tree(replay_with_teacher(advice, "random"), root / "shuffled.json")
    jobs = {
        "advised": [("ppo-shaped", s, root / "advice.json") for s in SEEDS],
        "shuffled": [("ppo-shaped", s, root / "shuffled.json") for s in SEEDS],
        "baseline": [("ppo", s, None) for s in SEEDS],
        "pilot": [("ppo", s, None) for s in PILOT_SEEDS],
    }
    with ProcessPoolExecutor(max_workers=2, mp_context=get_context("spawn")) as pool:
        futures = {
            arm: [pool.submit(_train, a, s, f, root / f"{arm}-{s}") for a, s, f in runs]
            for arm, runs in jobs.items()
        }
        return advice, {arm: [f.result() for f in fs] for arm, fs in futures.items()}


def _outcome(design, arm: str, judge: str) -> str:
    advice, runs = design
    arms = (runs[arm], runs["baseline"], runs["pilot"])
    result = runs_verdict(advice, arms, judge, np.random.default_rng(0))
    print(f"{arm} / {judge}: {result.text}")
    return result.outcome


def test_advice_at_scale_10_is_used(design) -> None:
    assert _outcome(design, "advised", "shaped-value") == "used"


def test_shuffled_advice_is_not_used(design) -> None:
    assert _outcome(design, "shuffled", "shaped-value") != "used"


@pytest.mark.parametrize("judge", ["return", "behaviour"])
def test_the_behaviour_judges_verdicts(design, judge: str) -> None:
    # Recorded (run with -s), not asserted: at this budget they may honestly say "cannot tell".
    assert _outcome(design, "advised", judge) in {"used", "no-different", "cannot-tell"}
