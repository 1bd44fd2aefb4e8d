"""Rewrite the values that ``tests/engine/rl/test_bit_identity.py`` compares against: this
machine's CPU capability's ``training-<capability>.json`` and ``judging-<capability>.json``.

Run it only for a change classed **number-altering** (one after which those tests fail, by
design or because nothing cheaper keeps the numbers), and say so in the commit message, with
what the change alters. A bit-identical change never regenerates: a test that fails after it
found a bug. From the repository root::

    .venv/bin/python -m tests.engine.rl.data.bit_identity.regenerate

It retrains the 3-update runs (under a minute on one core), rewrites the training file, then
re-measures the committed checkpoint and rewrites the judging file. The inputs, the bracket
``advice.json`` and the checkpoint ``judged.pt``, are kept; ``--inputs`` makes them anew first
(only when they no longer load): the bracket from :func:`engine.pipeline.run_tournament`, the
checkpoint from the new bipars-em run, cut to what judging loads.

A number-altering change can remake only this machine's capability's files; it deletes the
others in the same commit (they hold the old numbers), and says so.

**A machine with another CPU capability** (its tests fail: no file for it) gets its files from
the commit the other files were made by, never from the code under test, which is what the
files check: run this module in a copy of that commit (``git archive <commit> | tar -x -C
/tmp/frozen``, then ``PYTHONPATH=/tmp/frozen`` from ``/tmp/frozen``) and copy the two files it
writes here, named ``training-<capability>.json`` and ``judging-<capability>.json`` (commits
before the split write them without the suffix). Today that commit is ef285ec, round 2's
frozen training code; the AVX512 files were made so, on 2026-11-28.
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from pathlib import Path
from typing import Any

from engine.pipeline import run_tournament
from engine.rl.checkpoint import find_checkpoint, load_checkpoint, save_checkpoint
from engine.rl.config import ALGOS
from engine.rl.judge_cache import file_digest
from engine.treefile import dump_tree
from tests.engine.rl.test_bit_identity import (
    ADVICE,
    JUDGED,
    JUDGES,
    JUDGING,
    TRAINING,
    environment,
    judge_measures,
    training_numbers,
)

#: The checkpoint parts :func:`engine.rl.trained.load_agent` reads (``format`` and
#: ``timesteps`` are added by :func:`save_checkpoint`).
JUDGED_KEYS = ("config", "obs_dim", "act_dim", "agent", "obs_norm")
JUDGED_ALGO = "bipars-em"  # its actor reads z_phi(s): the judges' fullest forward pass


def write_json(path: Path, value: dict[str, Any]) -> None:
    """``value`` as JSON (floats as repr: exact), one field a line for readable diffs."""
    path.write_text(json.dumps(value, indent=1) + "\n")


def make_judged(run: Path) -> None:
    """``judged.pt``: the final checkpoint of ``run`` with only what judging loads."""
    state = load_checkpoint(find_checkpoint(run))
    with tempfile.TemporaryDirectory() as tmp:
        cut = {k: state[k] for k in JUDGED_KEYS}
        shutil.copyfile(save_checkpoint(cut, Path(tmp), state["timesteps"]), JUDGED)


def main(inputs: bool) -> None:
    """Retrain and re-measure; ``inputs``: make the bracket and the checkpoint anew first."""
    if inputs:
        tree = run_tournament(
            env_id="Humanoid-v5", n_candidates=16, p=0.9, seed=0, teacher="standing"
        )
        dump_tree(tree, ADVICE)
    with tempfile.TemporaryDirectory() as tmp:
        runs = {algo: training_numbers(algo, Path(tmp) / algo) for algo in ALGOS}
        write_json(TRAINING, {"environment": environment(), "runs": runs})
        if inputs:
            make_judged(Path(tmp) / JUDGED_ALGO)
    with tempfile.TemporaryDirectory() as tmp:
        measures = {judge: judge_measures(JUDGED, Path(tmp) / judge, judge) for judge in JUDGES}
    write_json(
        JUDGING,
        {
            "environment": environment(),
            "checkpoint_sha256": file_digest(JUDGED),
            "measures": measures,
        },
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="Rewrite the bit-identity expected values.")
    parser.add_argument(
        "--inputs", action="store_true", help="make advice.json and judged.pt anew first"
    )
    main(parser.parse_args().inputs)
