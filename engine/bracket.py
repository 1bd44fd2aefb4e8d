"""Braverman-Mossel seeding and single-elimination bracket structure.

Players are candidates; a player's ability is its state reward R(s). Following the paper, the
first-round pairings come from the Braverman-Mossel (BM) noisy comparison model [Braverman and
Mossel 2009]: every unordered pair gets ONE persistent outcome, a fair coin with probability
``p`` and otherwise the stronger player's win; players are ranked by their number of wins and
placed in a standard bracket (seed 1 meets seed 2 only in the final). With N not a power of two
the top seeds get first-round byes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from engine.errors import InputError

#: First-round slots in bracket order: ``(a, b)``, ``b is None`` for a bye.
FirstRound = list[tuple[int, int | None]]
#: Decided matches: ``(round, slot) -> winner id``; rounds count from 1.
Results = Mapping[tuple[int, int], int]


def bm_outcomes(abilities: np.ndarray, p: float, rng: np.random.Generator) -> np.ndarray:
    """Draw the persistent BM outcome of every unordered pair.

    Args:
        abilities: shape ``(N,)``.
        p: probability that a comparison is a fair coin; ``P(correct) = 1 - p / 2``.
        rng: random source.

    Returns:
        ``beats``, shape ``(N, N)`` bool: ``beats[i, j]`` iff i won the pair {i, j}. Exactly
        one of ``beats[i, j]``, ``beats[j, i]`` holds for ``i != j``.
    """
    if not 0.0 <= p <= 1.0:
        raise InputError(f"p must be in [0, 1], got {p}")
    n = len(abilities)
    i, j = np.triu_indices(n, k=1)
    coin = rng.random(len(i)) < p
    i_wins = np.where(coin, rng.random(len(i)) < 0.5, abilities[i] > abilities[j])
    # Equal abilities without a coin: no "stronger player", so a coin after all.
    tie = ~coin & (abilities[i] == abilities[j])
    i_wins[tie] = rng.random(int(tie.sum())) < 0.5
    beats = np.zeros((n, n), dtype=bool)
    beats[i[i_wins], j[i_wins]] = True
    beats[j[~i_wins], i[~i_wins]] = True
    return beats


def bm_ranking(abilities: np.ndarray, p: float, rng: np.random.Generator) -> np.ndarray:
    """Indices of players from seed 1 down: most BM wins first, ties broken by ``rng``."""
    wins = bm_outcomes(np.asarray(abilities, dtype=np.float64), p, rng).sum(axis=1)
    return np.lexsort((rng.permutation(len(wins)), -wins))


def seed_positions(size: int) -> list[int]:
    """Standard bracket order of seeds 1..size (a power of two), e.g. 8 -> 1 8 4 5 2 7 3 6."""
    order = [1]
    while len(order) < size:
        total = 2 * len(order) + 1
        order = [s for seed in order for s in (seed, total - seed)]
    return order


def make_first_round(
    ids: Sequence[int], abilities: np.ndarray, p: float, rng: np.random.Generator
) -> FirstRound:
    """BM-seeded first round for players ``ids`` (N >= 2), byes for the top seeds."""
    if len(ids) < 2:
        raise InputError(f"a bracket needs at least 2 candidates, got {len(ids)}")
    ranked = [ids[k] for k in bm_ranking(abilities, p, rng)]
    size = 1 << (len(ids) - 1).bit_length()
    by_seed = {
        seed: (ranked[seed - 1] if seed <= len(ids) else None) for seed in range(1, size + 1)
    }
    order = seed_positions(size)
    # the first of each pair is the better seed, at most size / 2 < len(ids): never a bye
    return [(cast(int, by_seed[order[k]]), by_seed[order[k + 1]]) for k in range(0, size, 2)]


@dataclass(frozen=True)
class Match:
    """One match of the bracket: ``round`` from 1, ``slot`` its index within the round."""

    round: int
    slot: int
    a: int
    b: int


class Bracket:
    """The structure of a single-elimination bracket, independent of who wins.

    Round ``r + 1`` slot ``k`` is played by the winners of round ``r`` slots ``2k`` and
    ``2k + 1``; a first-round bye passes its player on without a match.
    """

    def __init__(self, first_round: FirstRound):
        if len(first_round) < 1 or len(first_round) & (len(first_round) - 1):
            raise InputError("first round must have a power-of-two number of slots")
        players = [x for pair in first_round for x in pair if x is not None]
        if len(set(players)) != len(players) or any(a is None for a, _ in first_round):
            raise InputError("first round: each player once, byes only in second position")
        self.first_round = [(a, b) for a, b in first_round]
        self.n_rounds = len(first_round).bit_length()

    @property
    def players(self) -> list[int]:
        return [x for pair in self.first_round for x in pair if x is not None]

    @property
    def n_matches(self) -> int:
        return len(self.players) - 1

    def slot_players(self, results: Results) -> dict[tuple[int, int], tuple[int | None, ...]]:
        """Who plays each slot given ``results`` (``None`` where not yet known)."""
        slots: dict[tuple[int, int], tuple[int | None, ...]] = {}
        prev = [(1, k) for k in range(len(self.first_round))]
        for k, pair in enumerate(self.first_round):
            slots[(1, k)] = pair
        for rnd in range(2, self.n_rounds + 1):
            cur = [(rnd, k) for k in range(len(prev) // 2)]
            for k, key in enumerate(cur):
                slots[key] = (
                    self.winner(prev[2 * k], slots, results),
                    self.winner(prev[2 * k + 1], slots, results),
                )
            prev = cur
        return slots

    @staticmethod
    def winner(
        key: tuple[int, int], slots: dict[tuple[int, int], tuple[int | None, ...]], results: Results
    ) -> int | None:
        a, b = slots[key]
        return a if b is None and key[0] == 1 else results.get(key)

    def matches(self, results: Results) -> list[Match]:
        """All matches whose two players are known, in (round, slot) order."""
        return [
            Match(rnd, slot, a, b)
            for (rnd, slot), (a, b) in self.slot_players(results).items()
            if a is not None and b is not None
        ]

    def open_matches(self, results: Results) -> list[Match]:
        """Matches ready to be judged: both players known, no result yet."""
        return [m for m in self.matches(results) if (m.round, m.slot) not in results]

    def is_complete(self, results: Results) -> bool:
        return len(results) == self.n_matches and not self.open_matches(results)

    def check_result(self, match: Match, winner: int) -> None:
        if winner not in (match.a, match.b):
            raise InputError(
                f"winner {winner} did not play round {match.round} match {match.a} vs {match.b}"
            )
