"""Fit a Bradley-Terry reward model to the ``preferences`` of an ACV dataset.

Each row of the dataset's ``preferences`` config is one answered pair: the ``chosen`` and the
``rejected`` state as arrays (``*_observation``, ``*_posture``) and a ``tie`` flag. The
Bradley-Terry model, the reward model of preference-based RL (Christiano et al. 2017), reads
a pair as

    P(chosen preferred to rejected) = sigmoid(r(chosen) - r(rejected))

and fits the reward ``r``, here a small MLP on standardised features, by the cross-entropy of
those probabilities against the labels: 1 for a decided pair, 1/2 for a tie (the ``chosen``
side of a tie is a seeded coin's, not a preference).

Usage (needs ``torch`` and ``datasets``; a CPU takes seconds)::

    python examples/bradley_terry.py DATASET [--features observation|posture]
        [--epochs 300] [--batch-size 256] [--seed 0] [--out reward.pt] [--cache-dir DIR]
        [--json]

``DATASET`` is a folder that ``acv export --study ID --format hf --out DATASET`` wrote, an
unzipped ``dataset.zip``, or a Hub dataset id. ``--out`` saves the model's ``state_dict``
(standardisation included) with ``torch.save``; ``torch.load(path, weights_only=True)`` reads
it back.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass
from typing import Any

import torch
from datasets import load_dataset
from torch import nn
from torch.nn import functional


@dataclass(frozen=True)
class Pairs:
    """The answered pairs as tensors: ``chosen`` and ``rejected`` of shape ``(n, d)``, and the
    probability that ``chosen`` is preferred, ``target`` of shape ``(n,)``."""

    chosen: torch.Tensor
    rejected: torch.Tensor
    target: torch.Tensor


def load_pairs(source: str, features: str = "observation", cache_dir: str | None = None) -> Pairs:
    """The ``preferences`` of the dataset at ``source`` (a folder or a Hub id), with the
    states described by ``features`` (``observation`` or ``posture``)."""
    columns = [f"chosen_{features}", f"rejected_{features}", "tie"]
    data = load_dataset(source, "preferences", split="train", cache_dir=cache_dir)
    table = data.with_format("torch", columns=columns)[:]  # lists of one length: 2-D tensors
    chosen, rejected = (table[c].float() for c in columns[:2])
    return Pairs(chosen, rejected, torch.where(table["tie"], 0.5, 1.0))


class RewardModel(nn.Module):
    """``r(s)``: an MLP on features standardised with the dataset's mean and std (kept as
    buffers, so that the saved ``state_dict`` is the whole model)."""

    def __init__(self, mean: torch.Tensor, std: torch.Tensor, hidden: int = 64):
        super().__init__()
        self.register_buffer("mean", mean)
        self.register_buffer("std", std)
        self.net = nn.Sequential(nn.Linear(len(mean), hidden), nn.Tanh(), nn.Linear(hidden, 1))

    def forward(self, states: torch.Tensor) -> torch.Tensor:
        """The reward of each state: ``(n, d)`` -> ``(n,)``."""
        return self.net((states - self.mean) / self.std).squeeze(-1)


def bradley_terry_loss(model: RewardModel, pairs: Pairs) -> torch.Tensor:
    """The mean cross-entropy of ``sigmoid(r(chosen) - r(rejected))`` against the labels."""
    margin = model(pairs.chosen) - model(pairs.rejected)
    return functional.binary_cross_entropy_with_logits(margin, pairs.target)


def fit(pairs: Pairs, epochs: int = 300, batch_size: int = 256, seed: int = 0) -> RewardModel:
    """A reward model fitted with Adam on shuffled minibatches (seeded: the same data and
    seed give the same model on one machine)."""
    torch.manual_seed(seed)
    states = torch.cat([pairs.chosen, pairs.rejected])
    std = states.std(0)
    model = RewardModel(states.mean(0), torch.where(std > 1e-8, std, 1.0))
    optimiser = torch.optim.Adam(model.parameters(), lr=1e-2)
    n = len(pairs.target)
    for _ in range(epochs):
        for batch in torch.randperm(n).split(batch_size):
            part = Pairs(pairs.chosen[batch], pairs.rejected[batch], pairs.target[batch])
            optimiser.zero_grad()
            bradley_terry_loss(model, part).backward()
            optimiser.step()
    return model


@torch.no_grad()
def summary(model: RewardModel, pairs: Pairs, features: str) -> dict[str, Any]:
    """How well the model explains the pairs: its loss (``ln 2`` is a coin's) and the share
    of the decided pairs whose chosen state it rewards more."""
    decided = pairs.target == 1.0
    margin = model(pairs.chosen) - model(pairs.rejected)
    return {
        "pairs": len(pairs.target),
        "ties": int((~decided).sum()),
        "features": features,
        "dim": pairs.chosen.shape[1],
        "loss": bradley_terry_loss(model, pairs).item(),
        "chance_loss": math.log(2.0),
        "accuracy": (margin[decided] > 0).float().mean().item() if decided.any() else None,
    }


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Load, fit, report (and save with ``--out``); returns the report."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", help="a dataset folder or a Hub dataset id")
    parser.add_argument("--features", choices=("observation", "posture"), default="observation")
    parser.add_argument("--epochs", type=int, default=300)
    parser.add_argument("--batch-size", type=int, default=256)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", help="save the model's state_dict here")
    parser.add_argument("--cache-dir", help="the datasets cache (default: HF_DATASETS_CACHE)")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)  # a network this small only loses time to more threads' syncing
    pairs = load_pairs(args.dataset, args.features, args.cache_dir)
    model = fit(pairs, args.epochs, args.batch_size, args.seed)
    report = summary(model, pairs, args.features)
    if args.out:
        torch.save(model.state_dict(), args.out)
    print(json.dumps(report) if args.json else "\n".join(f"{k}: {v}" for k, v in report.items()))
    return report


if __name__ == "__main__":
    main()
