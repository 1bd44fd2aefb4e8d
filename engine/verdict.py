"""The verdict: did the advice change the agent? Advised runs against a matched no-advice
baseline, over seeds, on the matches that can tell (issue 25, docs/method.md §2.11).

1. **Informative matches.** A match ``(a, b, winner)`` of the advice is informative when the
   advice has a real preference, ``advice[winner] - advice[loser] >= margin_advice * spread``,
   and the *pilot* baseline has one, ``|pilot[a] - pilot[b]| >= margin_baseline * spread``,
   where ``pilot`` is the judge's score averaged over the pilot seeds and each ``spread`` is
   the range of those scores over the bracket's candidates (so the margins are shares of the
   scale, and mean the same for tree heights, F values or returns). Others are reported apart
   and never counted.
2. **Contested**: informative, and the pilot baseline's winner is not the advice's. The pilot
   runs are no-advice runs on seeds kept apart from the evaluation seeds: picking the matches
   with the evaluation baseline itself would push its agreement to near 0 by construction.
3. **CA** per run: the share of the contested matches whose winner the run's judge scores
   strictly higher (a tie keeps nothing). ``Δ = mean CA(advised) - mean CA(baseline)``.
4. **Decision**: the exact two-sided permutation test of the per-seed CAs at ``alpha``, with a
   crossed bootstrap interval of Δ and the AUC reported beside it (never deciding).
   :func:`engine.verdict_power.min_detectable_delta` gives the smallest Δ the design detects.

This module holds the verdict's data and steps 1-2; steps 3-4 and the verdict itself are
:func:`engine.verdict_outcome.verdict`, which builds on them (so they import nothing back).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from engine.conformance import contested_match
from engine.errors import InputError
from engine.treefile import TreeDocument

#: ``(a, b, winner)``: a match of the advice (a bracket match or a disagreement pair).
Pair = tuple[int, int, int]


@dataclass(frozen=True)
class VerdictOptions:
    """The verdict's settings (docs/method.md §2.11 says why these defaults).

    Attributes:
        margin_advice: share of the advice scores' spread that the winner must lead by.
        margin_baseline: share of the pilot's mean scores' spread that their gap must reach.
        min_contested: fewer informative contested matches than this is "cannot tell".
        alpha: the permutation test's two-sided level.
        power: the power at which the smallest detectable Δ is computed.
        seed_sd: the between-seed spread assumed by the smallest detectable Δ.
        n_boot: bootstrap draws of the interval.
    """

    margin_advice: float = 0.05
    margin_baseline: float = 0.05
    min_contested: int = 3
    alpha: float = 0.05
    power: float = 0.8
    seed_sd: float = 0.1
    n_boot: int = 2000


@dataclass(frozen=True)
class VerdictInputs:
    """Scores over one bracket's ``N`` candidates, ids ``0 .. N-1``.

    Attributes:
        advice: the advice's score per candidate, shape ``(N,)`` (see :func:`advice_scores`).
        advised: the judge's scores on the advised runs, shape ``(k_advised, N)``.
        baseline: the same judge on the no-advice evaluation runs, shape ``(k_baseline, N)``.
        pilot: the same judge on no-advice runs whose seeds are disjoint from the evaluation
            seeds, shape ``(k_pilot, N)``; they only pick the contested matches.
        matches: the advice's matches as ``(a, b, winner)``.
        reward: R per candidate, shape ``(N,)``, for the immediate-R contested matches (the
            judge's R; none reported when None).
    """

    advice: np.ndarray
    advised: np.ndarray
    baseline: np.ndarray
    pilot: np.ndarray
    matches: tuple[Pair, ...]
    reward: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = np.shape(self.advice)[0] if np.ndim(self.advice) == 1 else -1
        if n < 2:
            raise InputError("advice scores must be a flat array over at least 2 candidates")
        for name in ("advised", "baseline", "pilot"):
            if np.ndim(getattr(self, name)) != 2 or np.shape(getattr(self, name))[1] != n:
                raise InputError(f"{name} scores must have shape (seeds, {n})")
        if self.reward is not None and np.shape(self.reward) != (n,):
            raise InputError(f"reward must have shape ({n},)")
        for a, b, w in self.matches:
            if not (0 <= a < n and 0 <= b < n and a != b and w in (a, b)):
                raise InputError(f"match ({a}, {b}, winner {w}) is not a match over {n} ids")


@dataclass(frozen=True)
class MatchClasses:
    """The matches of :class:`VerdictInputs`, split (module docstring, steps 1-2).

    Attributes:
        contested: informative, the pilot baseline picks the other winner; these are counted.
        agreed: informative, the pilot baseline picks the advice's winner too.
        uninformative: the advice or the pilot baseline has no real preference; never counted.
        r_contested: informative matches whose winner has the strictly lower R (reported
            beside the contested ones; empty without R).
    """

    contested: tuple[Pair, ...]
    agreed: tuple[Pair, ...]
    uninformative: tuple[Pair, ...]
    r_contested: tuple[Pair, ...] = ()


@dataclass(frozen=True)
class Verdict:
    """The verdict and everything it rests on.

    Attributes:
        outcome: ``used``, ``against``, ``no-different`` or ``cannot-tell``.
        label: the outcome in words ("used your advice", ...).
        reason: why "cannot tell" (None otherwise).
        matches: the split of the matches considered.
        ca_advised: per advised seed, the share of contested matches kept, shape ``(k_a,)``.
        ca_baseline: the same per baseline evaluation seed, shape ``(k_b,)``.
        delta: mean CA advised minus mean CA baseline (None without contested matches or runs).
        interval: 95% crossed-bootstrap interval of ``delta``.
        p_value: the two-sided permutation test's p.
        auc: P(advised CA > baseline CA), ties counted half.
        min_detectable_delta: smallest Δ detected at ``alpha`` with the options' power; None
            when no Δ is.
        alpha: the test's level.
        power: the power of ``min_detectable_delta``.
        text: the one-sentence verdict.
    """

    outcome: str
    label: str
    reason: str | None
    matches: MatchClasses
    ca_advised: tuple[float, ...]
    ca_baseline: tuple[float, ...]
    delta: float | None
    interval: tuple[float, float] | None
    p_value: float | None
    auc: float | None
    min_detectable_delta: float | None
    alpha: float
    power: float
    text: str = field(default="")

    def to_json(self) -> dict[str, Any]:
        """JSON-ready data for the API and ``--json`` (tuples as lists)."""
        out = asdict(self)
        out["matches"] = {k: [list(p) for p in v] for k, v in out["matches"].items()}
        out["ca_advised"], out["ca_baseline"] = list(self.ca_advised), list(self.ca_baseline)
        out["interval"] = None if self.interval is None else list(self.interval)
        out["n_contested"] = len(self.matches.contested)
        return out

    @classmethod
    def from_json(cls, obj: dict[str, Any]) -> Verdict:
        """Inverse of :meth:`to_json`."""
        fields = {k: v for k, v in obj.items() if k != "n_contested"}
        fields["matches"] = MatchClasses(
            **{k: tuple(tuple(p) for p in v) for k, v in obj["matches"].items()}
        )
        fields["ca_advised"], fields["ca_baseline"] = (
            tuple(obj["ca_advised"]),
            tuple(obj["ca_baseline"]),
        )
        fields["interval"] = None if obj["interval"] is None else tuple(obj["interval"])
        return cls(**fields)


def advice_scores(doc: TreeDocument) -> np.ndarray:
    """The advice's score per candidate: its recorded judge scores where the tree has them,
    else the candidates' heights (rounds won), which every winner leads its loser by >= 1
    except at a tie, where the loser is raised (docs/method.md §2.14) and the winner may
    lead by 0."""
    if doc.scores is not None:
        return np.array([doc.scores[c.id] for c in doc.candidates], dtype=np.float64)
    return np.array([doc.tree.nodes[c.id].height for c in doc.candidates], dtype=np.float64)


def bracket_pairs(doc: TreeDocument) -> tuple[Pair, ...]:
    """The tree's matches as ``(a, b, winner)``, leaving out those its judge could not tell:
    a tie is never contested and neither kept nor rejected (docs/method.md §2.14)."""
    return tuple((m.a, m.b, w) for m, w in doc.untied_matches)


def classify(inputs: VerdictInputs, options: VerdictOptions = VerdictOptions()) -> MatchClasses:
    """Split the matches into contested, agreed and uninformative (module docstring)."""
    pilot = inputs.pilot.mean(axis=0) if len(inputs.pilot) else np.zeros_like(inputs.advice)
    return split_matches(inputs.advice, pilot, inputs.matches, options, inputs.reward)


def split_matches(
    advice: np.ndarray,
    baseline: np.ndarray,
    matches: tuple[Pair, ...],
    options: VerdictOptions = VerdictOptions(),
    reward: np.ndarray | None = None,
) -> MatchClasses:
    """Split ``matches`` by the advice's and one baseline's preferences.

    Also what a study shows before any baseline is trained: pass R as ``baseline`` (an agent
    that goes by R alone) to estimate how many matches can tell.

    Args:
        advice: the advice's score per candidate, shape ``(N,)``.
        baseline: the no-advice scores that pick the contested matches, shape ``(N,)`` (the
            pilot runs' mean).
        matches: ``(a, b, winner)`` of the advice.
        options: the margins.
        reward: R per candidate, shape ``(N,)``, for the immediate-R contested matches.
    """
    min_advice = options.margin_advice * np.ptp(advice)
    min_baseline = options.margin_baseline * np.ptp(baseline)
    contested: list[Pair] = []
    agreed: list[Pair] = []
    uninformative: list[Pair] = []
    for a, b, w in matches:
        loser = b if w == a else a
        lead, base_lead = advice[w] - advice[loser], baseline[w] - baseline[loser]
        if lead <= 0 or lead < min_advice or base_lead == 0 or abs(base_lead) < min_baseline:
            uninformative.append((a, b, w))
        else:
            (agreed if base_lead > 0 else contested).append((a, b, w))
    r_map = {} if reward is None else dict(enumerate(reward.tolist()))
    r_contested = tuple(p for p in contested + agreed if r_map and contested_match(r_map, *p))
    return MatchClasses(tuple(contested), tuple(agreed), tuple(uninformative), r_contested)


def kept(scores: np.ndarray, pairs: tuple[Pair, ...]) -> np.ndarray:
    """Whether each run keeps each match: the winner scores strictly higher, shape ``(k, n)``."""
    winners = np.array([w for _, _, w in pairs], dtype=np.intp)
    losers = np.array([b if w == a else a for a, b, w in pairs], dtype=np.intp)
    out: np.ndarray = scores[:, winners] > scores[:, losers]
    return out
