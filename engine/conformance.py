"""Conformance metrics between a Human and an Agent Preference Tree over the same bracket.

- match agreement: the share of the human's matches in which the agent's judge picks the same
  winner, with a Wilson 95% interval. The agent's pick is its own result where it played the
  same pair in the same round, else the higher of its recorded judge scores, else the one it
  ranks higher (more rounds won); an unresolved tie counts as not agreeing.
- Kendall tau-b between the candidates' heights (rounds won) in the two trees.
- normalised tree edit distance: Zhang-Shasha distance (zss) with unit costs and children in
  canonical order, divided by ``n_human + n_agent`` so that it lies in [0, 1].
- same champion, and the *rejected advice*: the human's matches the agent overturned.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import zss
from scipy.stats import binomtest, kendalltau

from engine.errors import InputError
from engine.preference_tree import PreferenceTree
from engine.treefile import TreeDocument


@dataclass(frozen=True)
class Rejection:
    """A human match the agent decided the other way."""

    round: int
    a: int
    b: int
    human_winner: int
    agent_winner: int | None


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

    def to_json(self) -> dict:
        out = asdict(self)
        out["match_agreement_ci"] = list(self.match_agreement_ci)
        return out


def compare(human: TreeDocument, agent: TreeDocument) -> Conformance:
    """Conformance of ``agent``'s tree to ``human``'s; both must share one bracket."""
    check_same_bracket(human, agent)
    if not human.matches:  # binomtest needs n >= 1
        raise InputError("the trees have no matches to compare (fewer than 2 candidates)")
    rejected, agree = [], 0
    for m, human_winner in human.matches:
        pick = agent_pick(agent, m.round, m.a, m.b)
        if pick == human_winner:
            agree += 1
        else:
            rejected.append(Rejection(m.round, m.a, m.b, human_winner, pick))
    n = len(human.matches)
    ci = binomtest(agree, n).proportion_ci(confidence_level=0.95, method="wilson")
    return Conformance(n, agree, agree / n, (float(ci.low), float(ci.high)),
                       heights_tau(human.tree, agent.tree), tree_edit_distance(human.tree,
                                                                               agent.tree),
                       human.tree.root == agent.tree.root, rejected)


def check_same_bracket(human: TreeDocument, agent: TreeDocument) -> None:
    """Raise :class:`InputError` unless both documents share candidates and first round."""
    same = (human.env_id == agent.env_id and human.first_round == agent.first_round
            and len(human.candidates) == len(agent.candidates)
            and all(np.array_equal(h.qpos, a.qpos) and np.array_equal(h.qvel, a.qvel)
                    for h, a in zip(human.candidates, agent.candidates, strict=True)))
    if not same:
        raise InputError("the two trees are over different brackets (candidates, env or "
                         "first round differ): replay the human's tree to compare")


def agent_pick(agent: TreeDocument, rnd: int, a: int, b: int) -> int | None:
    """The agent's choice between ``a`` and ``b`` (see the module docstring)."""
    for m, winner in agent.matches:
        if m.round == rnd and {m.a, m.b} == {a, b}:
            return winner
    if agent.scores is not None and agent.scores[a] != agent.scores[b]:
        return a if agent.scores[a] > agent.scores[b] else b
    ha, hb = agent.tree.nodes[a].height, agent.tree.nodes[b].height
    return None if ha == hb else (a if ha > hb else b)


def heights_tau(human: PreferenceTree, agent: PreferenceTree) -> float | None:
    """Kendall tau-b of heights over all candidates; ``None`` when undefined."""
    ids = sorted(human.nodes)
    tau = kendalltau([human.nodes[i].height for i in ids], [agent.nodes[i].height for i in ids],
                     variant="b").statistic
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
