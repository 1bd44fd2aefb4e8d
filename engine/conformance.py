"""Conformance metrics between a Human and an Agent Preference Tree over the same bracket.

- match agreement: the share of the human's matches in which the agent's judge picks the same
  winner, with a Wilson 95% interval. The agent's pick is the higher of its recorded judge
  scores when its judge scores (a tie is no preference); else its own result where it played
  the same pair in the same round, else the one it ranks higher (more rounds won). A tie
  counts as not agreeing.
- Kendall tau-b between the candidates' heights (rounds won) in the two trees.
- normalised tree edit distance: Zhang-Shasha distance (zss) with unit costs and children in
  canonical order, divided by ``n_human + n_agent`` so that it lies in [0, 1].
- same champion, and the *rejected advice*: the human's matches the agent overturned.
- *contested* matches: the human's matches whose winner has the lower environment reward R
  (by default the stored ``env_reward``; callers may pass another R map, such as the judge's
  R with the control cost). A judge that ignored the advice and went by R would overturn
  them; keeping an uncontested match proves nothing, so the verdict leads with these.
- reference agreement: the match agreement that an R-only judge scores against the human,
  that is, what ignoring the advice would score.

Ties are handled one way everywhere, by :func:`engine.tournament.score_winner` (which
:class:`engine.tournament.ScoreJudge` uses too): equal scores express no preference, so a
match tied in R is neither contested nor one that the R-only judge agrees with, and a match
the agent's scores tie is one it does not keep.

A match the *human* could not tell (``TreeDocument.ties``, docs/method.md §2.14) carries no
advice: it is never contested, never rejected, and counts as neither agreement nor
disagreement (it is left out of every numerator and denominator). A match the agent's own
document marks as tied is, like a tie in its scores, no preference.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import scipy
import zss

from engine.bracket import Match
from engine.errors import InputError
from engine.preference_tree import PreferenceTree
from engine.tournament import score_winner
from engine.treefile import TreeDocument


@dataclass(frozen=True)
class Rejection:
    """A human match the agent decided the other way."""

    round: int
    a: int
    b: int
    human_winner: int
    agent_winner: int | None
    contested: bool = False
    """the human's winner has the lower environment reward R"""


@dataclass(frozen=True)
class Contested:
    """Agreement over the human's contested matches (winner with the lower R).

    Attributes:
        n: contested matches.
        kept: of those, decided the human's way by the agent.
        agreement: ``kept / n``; None without contested matches.
        agreement_ci: Wilson 95% interval of ``agreement``; None without contested matches.
    """

    n: int
    kept: int
    agreement: float | None
    agreement_ci: tuple[float, float] | None


@dataclass(frozen=True)
class Conformance:
    """The metrics of :func:`compare` (see the module docstring)."""

    n_matches: int
    n_agree: int
    match_agreement: float
    match_agreement_ci: tuple[float, float]
    kendall_tau_b: float | None
    tree_edit_distance: float
    same_champion: bool
    rejected: list[Rejection]
    contested: Contested
    reference_agreement: float

    def to_json(self) -> dict[str, Any]:
        """The JSON of ``acv compare --json`` (tuples as lists)."""
        out = asdict(self)
        out["match_agreement_ci"] = list(self.match_agreement_ci)
        ci = self.contested.agreement_ci
        out["contested"]["agreement_ci"] = None if ci is None else list(ci)
        return out

    @classmethod
    def from_json(cls, obj: dict[str, Any]) -> Conformance:
        """Inverse of :meth:`to_json`."""
        fields = dict(obj)
        ci = obj["contested"]["agreement_ci"]
        fields["contested"] = Contested(
            **{**obj["contested"], "agreement_ci": None if ci is None else tuple(ci)}
        )
        fields["rejected"] = [Rejection(**r) for r in obj["rejected"]]
        fields["match_agreement_ci"] = tuple(obj["match_agreement_ci"])
        return cls(**fields)


def compare(
    human: TreeDocument, agent: TreeDocument, reward: Mapping[int, float] | None = None
) -> Conformance:
    """Conformance of ``agent``'s tree to ``human``'s; both must share one bracket.

    Args:
        human: the advice tree.
        agent: the tree compared with it.
        reward: candidate id -> R that decides which matches are contested and the reference
            agreement; the stored ``env_reward`` when None.
    """
    check_same_bracket(human, agent)
    matches = _advice_matches(human)
    reward = stored_reward(human) if reward is None else reward
    rejected, agree, contested, contested_kept = [], 0, 0, 0
    for m, human_winner in matches:
        pick = agent_pick(agent, m.round, m.a, m.b)
        is_contested = contested_match(reward, m.a, m.b, human_winner)
        contested += is_contested
        if pick == human_winner:
            agree += 1
            contested_kept += is_contested
        else:
            rejected.append(Rejection(m.round, m.a, m.b, human_winner, pick, is_contested))
    n = len(matches)
    return Conformance(
        n,
        agree,
        agree / n,
        wilson(agree, n),
        heights_tau(human.tree, agent.tree),
        tree_edit_distance(human.tree, agent.tree),
        human.tree.root == agent.tree.root,
        rejected,
        _contested(contested_kept, contested),
        reference_agreement(human, reward),
    )


def _advice_matches(human: TreeDocument) -> list[tuple[Match, int]]:
    """The human's matches that carry a preference (ties left out); at least one.

    Raises:
        InputError: no such match (binomtest and every share need ``n >= 1``).
    """
    if not human.matches:
        raise InputError("the trees have no matches to compare (fewer than 2 candidates)")
    if not (matches := human.untied_matches):
        raise InputError("every match of the human's tree is a tie: there is no advice to compare")
    return matches


def stored_reward(doc: TreeDocument) -> dict[int, float]:
    """Candidate id -> the stored ``env_reward`` (R without the control cost)."""
    return {c.id: c.env_reward for c in doc.candidates}


def contested_match(reward: Mapping[int, float], a: int, b: int, winner: int) -> bool:
    """Whether ``winner`` of ``a`` vs ``b`` has the strictly lower R (a tie is not contested)."""
    r_pick = score_winner(reward, a, b)
    return r_pick is not None and r_pick != winner


def _contested(kept: int, n: int) -> Contested:
    return Contested(n, kept, kept / n if n else None, wilson(kept, n) if n else None)


def wilson(k: int, n: int) -> tuple[float, float]:
    """Wilson 95% interval of ``k`` successes in ``n >= 1`` trials."""
    ci = scipy.stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)


def reference_agreement(human: TreeDocument, reward: Mapping[int, float] | None = None) -> float:
    """The match agreement of an R-only judge with ``human``: the share of the human's untied
    matches won by the higher-R candidate (a tie in R counts as not agreeing).

    Args:
        human: the advice tree.
        reward: candidate id -> R; the stored ``env_reward`` when None.

    Raises:
        InputError: the human's tree has no untied match.
    """
    matches = _advice_matches(human)
    reward = stored_reward(human) if reward is None else reward
    agree = sum(score_winner(reward, m.a, m.b) == w for m, w in matches)
    return agree / len(matches)


def check_same_bracket(human: TreeDocument, agent: TreeDocument) -> None:
    """Raise :class:`InputError` unless both documents share candidates and first round."""
    same = (
        human.env_id == agent.env_id
        and human.first_round == agent.first_round
        and len(human.candidates) == len(agent.candidates)
        and all(
            np.array_equal(h.qpos, a.qpos) and np.array_equal(h.qvel, a.qvel)
            for h, a in zip(human.candidates, agent.candidates, strict=True)
        )
    )
    if not same:
        raise InputError(
            "the two trees are over different brackets (candidates, env or "
            "first round differ): replay the human's tree to compare"
        )


def agent_pick(agent: TreeDocument, rnd: int, a: int, b: int) -> int | None:
    """The agent's choice between ``a`` and ``b`` (see the module docstring)."""
    if agent.scores is not None:  # a judge that scores: a tie is no preference (score_winner)
        return score_winner(agent.scores, a, b)
    for m, winner in agent.matches:
        if m.round == rnd and {m.a, m.b} == {a, b}:
            return None if agent.tied(m) else winner  # a tie is no preference
    ha, hb = agent.tree.nodes[a].height, agent.tree.nodes[b].height
    return None if ha == hb else (a if ha > hb else b)


def heights_tau(human: PreferenceTree, agent: PreferenceTree) -> float | None:
    """Kendall tau-b of heights over all candidates; ``None`` when undefined."""
    ids = sorted(human.nodes)
    tau = scipy.stats.kendalltau(
        [human.nodes[i].height for i in ids], [agent.nodes[i].height for i in ids], variant="b"
    ).statistic
    return None if np.isnan(tau) else float(tau)


def tree_edit_distance(t1: PreferenceTree, t2: PreferenceTree) -> float:
    """Zhang-Shasha distance over node labels (state ids), normalised to [0, 1]."""
    return float(zss.simple_distance(_zss(t1), _zss(t2))) / (len(t1) + len(t2))


def _zss(tree: PreferenceTree) -> zss.Node:
    nodes = {s: zss.Node(s) for s in tree.nodes}
    for s, node in tree.nodes.items():
        for c in sorted(node.children):  # canonical order: by state id, same in both trees
            nodes[s].addkid(nodes[c])
    return nodes[tree.root]
