"""Dendrogram -> Preference Tree (the paper's Algorithm 1) and the tree reward T_r.

A Preference Tree condenses the dendrogram so that every state appears once: the root is the
champion, and the children of a node are the players it beat. Edge weight
``w(i, j) = height(i) - height(j)`` with heights from the dendrogram (leaves 0); a state's
height is that of its topmost dendrogram node, i.e. the last match it won.

The paper defines no tie. ACV's (docs/method.md §2.14): the seeded coin's loser of a match the
judge could not tell is rewarded as if it had won that match too, its height raised to that
match's dendrogram node, so ``T_r = r_e * height - r_b`` still holds at every node.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from engine.tournament import DendroNode


@dataclass(frozen=True)
class PrefNode:
    """A Preference Tree node.

    Attributes:
        state: candidate id.
        parent: the state that beat it; ``None`` for the root.
        height: dendrogram height of its topmost node (rounds it won, counting byes' effect);
            for the coin's loser of a tie, the tied match node's height.
        depth: 1 for the root, parent's depth + 1 otherwise.
        weight: ``height(parent) - height(state)``; ``None`` for the root.
        reward: the tree reward T_r(state).
        children: the states it beat, latest round first.
    """

    state: int
    parent: int | None
    height: int
    depth: int
    weight: int | None
    reward: float
    children: tuple[int, ...]


@dataclass(frozen=True)
class PreferenceTree:
    """A Preference Tree: ``nodes`` maps state id -> node, in pre-order from the root."""

    root: int
    nodes: dict[int, PrefNode]

    def __len__(self) -> int:
        return len(self.nodes)

    @property
    def leaves(self) -> list[int]:
        return [s for s, node in self.nodes.items() if not node.children]


def from_dendrogram(
    root: DendroNode,
    r_b: float = 1.0,
    r_e: float = 1.0,
    raised: Mapping[int, int] | None = None,
) -> PreferenceTree:
    """Algorithm 1: depth-first walk; a child with its parent's value is skipped into.

    Args:
        root: the dendrogram's root (the final).
        r_b: the leaves' reward is ``-r_b`` (positive constant).
        r_e: reward per unit of edge weight (positive constant).
        raised: state -> height for the coin's losers of tied matches
            (:func:`engine.tournament.tie_heights`): each is rewarded as if it had won its
            tied match too (docs/method.md §2.14). Its height becomes the tied match node's,
            which its winner held right after that match, so ``w(winner, loser) >= 0``.
    """
    raised = raised or {}
    heights = {root.value: root.height}
    parents: dict[int, int | None] = {root.value: None}
    children: dict[int, list[int]] = {root.value: []}

    def recurse(head: DendroNode, tree_node: int) -> None:
        for child in head.children:
            if child.value == head.value:  # the same player's earlier match: skip into it
                recurse(child, tree_node)
            else:
                heights[child.value] = raised.get(child.value, child.height)
                parents[child.value] = tree_node
                children[child.value] = []
                children[tree_node].append(child.value)
                recurse(child, child.value)

    recurse(root, root.value)
    return build(root.value, parents, heights, children, r_b, r_e)


def build(
    root: int,
    parents: dict[int, int | None],
    heights: dict[int, int],
    children: dict[int, list[int]],
    r_b: float,
    r_e: float,
) -> PreferenceTree:
    """Assemble the tree from parent links and heights: depths, weights and rewards."""
    order = {s: sorted(kids, key=lambda c: (-heights[c], c)) for s, kids in children.items()}
    rewards = tree_reward(root, order, heights, r_b, r_e)
    nodes: dict[int, PrefNode] = {}
    stack = [(root, 1)]
    while stack:
        state, depth = stack.pop()
        parent = parents[state]
        weight = None if parent is None else heights[parent] - heights[state]
        nodes[state] = PrefNode(
            state, parent, heights[state], depth, weight, rewards[state], tuple(order[state])
        )
        stack.extend((c, depth + 1) for c in reversed(order[state]))
    return PreferenceTree(root, nodes)


def tree_reward(
    root: int, children: dict[int, list[int]], heights: dict[int, int], r_b: float, r_e: float
) -> dict[int, float]:
    """T_r by the paper's bottom-up recursion (Eq. 1), as written.

    ``T_r(s) = -r_b`` for a leaf, else ``mean_c (T_r(c) + r_e * w(s, c))``. It telescopes to
    ``r_e * height(s) - r_b``, which the tests use as an oracle. A leaf raised by a tie
    (height ``h > 0``, :func:`from_dendrogram`) won its tied match as if against a copy of
    itself at height 0, so it gets ``-r_b + r_e * h``; the identity then holds everywhere.
    """
    rewards: dict[int, float] = {}
    post_order: list[int] = []
    stack = [root]
    while stack:  # iterative: a 128-player chain would be deep for Python recursion
        s = stack.pop()
        post_order.append(s)
        stack.extend(children[s])
    for s in reversed(post_order):
        kids = children[s]
        rewards[s] = (
            _leaf_reward(heights[s], r_b, r_e)
            if not kids
            else sum(rewards[c] + r_e * (heights[s] - heights[c]) for c in kids) / len(kids)
        )
    return rewards


def _leaf_reward(height: int, r_b: float, r_e: float) -> float:
    """``-r_b`` for a leaf, the paper's; a tie-raised leaf adds ``r_e`` per raised level.

    Exactly ``-r_b`` at height 0 (not ``-r_b + 0.0``, which would turn ``-0.0`` into ``0.0``
    and change the bytes of a stored tree with ``r_b = 0``).
    """
    return -r_b if height == 0 else r_e * height - r_b
