"""An imported policy's judge scores: ``behaviour`` and ``return``, as for ACV's own runs.

The two verdict judges read only what a policy *does* (:mod:`engine.rl.behaviour`,
:mod:`engine.rl.returns`), so an imported policy is judged by the same code: its rollouts run
in a limited child (:mod:`engine.policies.sandbox`), and the scores are derived from them here
exactly as :func:`engine.rl.agent_judge.agent_scores` derives a checkpoint's. The rollouts are
cached under the same names, keyed by :attr:`ImportedPolicy.digest` instead of a checkpoint's
hash. The other judges read ACV's critic and z_phi, which an imported policy has not.
"""

from __future__ import annotations

from pathlib import Path

from engine.errors import InputError
from engine.judges import VERDICT_JUDGES, judge_name
from engine.policies.onnx_policy import ImportedPolicy
from engine.policies.sandbox import ChildLimits, ReturnJob, VisitJob, run_in_child
from engine.rl.behaviour import RolloutOptions, behaviour_cache_name, occupancy_scores
from engine.rl.judge_cache import cached_array
from engine.rl.returns import ReturnOptions, candidate_states, mean_returns, return_cache_name
from engine.treefile import TreeDocument


def imported_scores(
    policy: ImportedPolicy,
    doc: TreeDocument,
    judge: str = "return",
    *,
    cache_dir: Path | None = None,
    rollouts: RolloutOptions = RolloutOptions(),
    returns: ReturnOptions = ReturnOptions(),
    limits: ChildLimits = ChildLimits(),
) -> dict[int, float]:
    """The policy's score of every candidate of ``doc`` under ``judge``.

    Args:
        policy: a checked model and its normalisation.
        doc: the tree whose candidates are scored (on the policy's env).
        judge: ``return`` or ``behaviour``.
        cache_dir: where the rollouts are cached (``<cache_dir>/rollouts/``); None for none.
        rollouts: the behaviour judge's rollouts.
        returns: the return judge's rollouts.
        limits: the judging child's memory and time.

    Raises:
        InputError: another judge or env, or the child failed (out of time or memory).
    """
    judge = judge_name(judge)
    if judge not in VERDICT_JUDGES:
        raise InputError(
            f"an imported policy is judged by {' or '.join(VERDICT_JUDGES)}: {judge!r} reads "
            "ACV's critic or shaping weight, which it has not"
        )
    if doc.env_id != policy.env_id:
        raise InputError(f"the tree is for {doc.env_id}, but the policy is for {policy.env_id}")
    if judge == "behaviour":
        visited = cached_array(
            cache_dir,
            behaviour_cache_name(policy.digest, rollouts),
            lambda: run_in_child(VisitJob(policy, rollouts), limits),
        )
        return occupancy_scores(visited, doc)
    qpos, qvel = candidate_states(doc)
    scores = cached_array(
        cache_dir,
        return_cache_name(policy.digest, doc, returns),
        lambda: run_in_child(ReturnJob(policy, qpos, qvel, returns), limits),
    )
    return mean_returns(doc, scores)
