"""Everything ACV shows about one checkpoint, computed once where the run lives.

:func:`checkpoint_report` loads a checkpoint once and gives, for every judge of
:data:`engine.judges.JUDGES`, the Agent Preference Tree over the advice bracket and its
conformance to the advice tree, plus the per-candidate table that explains them (R, F, z, z F,
V, the behaviour score and the return). The executor stores :meth:`CheckpointReport.to_json`
for the web tier, which then only reads. Reports stored before ``value`` was renamed
``shaped-value`` read with the new name.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from engine.conformance import Conformance, compare
from engine.errors import InputError
from engine.judges import JUDGES, LEGACY_JUDGES
from engine.records import CandidateRow
from engine.rl.agent_judge import agent_scores, replay_as, run_advice_fn
from engine.rl.behaviour import RolloutOptions
from engine.rl.checkpoint import find_checkpoint
from engine.rl.returns import ReturnOptions
from engine.rl.reward_terms import CandidateTerms, candidate_terms, term_scores
from engine.rl.runner import load_run_advice
from engine.rl.trained import TrainedAgent, load_agent
from engine.treefile import TreeDocument, tree_from_json, tree_to_json

SCHEMA = "acv.checkpoint/1"


@dataclass(frozen=True)
class JudgeResult:
    """One judge's Agent Preference Tree and its conformance to the advice tree."""

    judge: str
    tree: TreeDocument
    conformance: Conformance


@dataclass(frozen=True)
class CheckpointReport:
    """The agent at one checkpoint: every judge's tree and conformance, and the table.

    Attributes:
        step: the checkpoint's timesteps.
        judges: one :class:`JudgeResult` per judge of :data:`JUDGES`, by name.
        candidates: one :class:`CandidateRow` per candidate, by id.
    """

    step: int
    judges: dict[str, JudgeResult]
    candidates: list[CandidateRow]

    def to_json(self) -> dict[str, Any]:
        """``{"schema", "step", "judges": {name: {"tree", "conformance"}}, "candidates"}``."""
        return {
            "schema": SCHEMA,
            "step": self.step,
            "judges": {
                name: {"tree": tree_to_json(r.tree), "conformance": r.conformance.to_json()}
                for name, r in self.judges.items()
            },
            "candidates": [asdict(row) for row in self.candidates],
        }

    @classmethod
    def from_json(cls, obj: dict[str, Any]) -> CheckpointReport:
        """Inverse of :meth:`to_json`.

        Raises:
            InputError: not an ``acv.checkpoint/1`` document.
        """
        if not isinstance(obj, dict) or obj.get("schema") != SCHEMA:
            raise InputError(f"not an {SCHEMA} document")
        judges = {}
        for stored, r in obj["judges"].items():
            name = LEGACY_JUDGES.get(stored, stored)
            judges[name] = JudgeResult(
                name, tree_from_json(r["tree"]), Conformance.from_json(r["conformance"])
            )
        return cls(int(obj["step"]), judges, [CandidateRow(**row) for row in obj["candidates"]])


def checkpoint_report(
    run_dir: Path,
    step: int | None = None,
    advice: TreeDocument | None = None,
    *,
    rollouts: RolloutOptions = RolloutOptions(),
    returns: ReturnOptions = ReturnOptions(),
) -> CheckpointReport:
    """Every judge's tree and conformance, and the per-candidate table, at one checkpoint.

    Args:
        run_dir: the training run directory.
        step: checkpoint timesteps; the latest when None.
        advice: the tree to replay and compare with; by default the run's ``advice.json``
            (a ``ppo`` run has none: pass the bracket it is to be judged on).
        rollouts: the behaviour judge's rollouts.
        returns: the return judge's rollouts.

    Raises:
        InputError: no advice tree, no such checkpoint, a damaged checkpoint, another env.
    """
    own = load_run_advice(run_dir)
    doc = advice if advice is not None else own
    if doc is None:
        raise InputError(f"{run_dir} was trained without advice: pass the tree to compare with")
    trained = load_agent(find_checkpoint(run_dir, step))
    return trained_report(trained, doc, own, run_dir=run_dir, rollouts=rollouts, returns=returns)


def members_conformance(
    report: CheckpointReport, members: Sequence[TreeDocument]
) -> list[dict[str, Conformance]]:
    """Pooled advice: each member's tree judged by every judge's Agent Preference Tree.

    The agent's trees replay the pooled verdict's bracket, which every member's tree shares,
    so each member's conformance is the same :func:`compare` as the report's own (the pooled
    verdict's): one ``{judge: Conformance}`` per member, in order.

    Raises:
        InputError: a member's tree over another bracket.
    """
    return [
        {name: compare(member, r.tree) for name, r in report.judges.items()} for member in members
    ]


def trained_report(
    trained: TrainedAgent,
    doc: TreeDocument,
    own: TreeDocument | None,
    *,
    run_dir: Path | None = None,
    rollouts: RolloutOptions = RolloutOptions(),
    returns: ReturnOptions = ReturnOptions(),
) -> CheckpointReport:
    """:func:`checkpoint_report` for a checkpoint already loaded (F from ``own``, the run's
    advice tree, when it has one)."""
    f = run_advice_fn(trained, own, run_dir)
    terms = candidate_terms(trained, doc, f)
    scores = {
        judge: agent_scores(
            trained, doc, judge, f, run_dir=run_dir, rollouts=rollouts, returns=returns
        )
        if judge in ("behaviour", "return")
        else term_scores(terms, judge, doc)
        for judge in JUDGES
    }
    judges = {}
    for judge in JUDGES:
        tree = replay_as(trained, doc, judge, scores[judge])
        judges[judge] = JudgeResult(judge, tree, compare(doc, tree))
    return CheckpointReport(
        trained.timesteps, judges, _rows(terms, doc, scores["behaviour"], scores["return"])
    )


def _rows(
    terms: CandidateTerms,
    doc: TreeDocument,
    behaviour: dict[int, float],
    env_return: dict[int, float],
) -> list[CandidateRow]:
    return [
        CandidateRow(
            c.id,
            float(terms.reward[i]),
            float(terms.advice[i]),
            float(terms.z[i]),
            float(terms.shaping[i]),
            float(terms.shaped[i]),
            float(terms.value[i]),
            behaviour[c.id],
            env_return[c.id],
        )
        for i, c in enumerate(doc.candidates)
    ]
