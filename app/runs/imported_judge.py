"""An imported policy judged as ACV's own runs are: its one checkpoint's report, stored once.

A worker claims an imported run like any queued run, and its executor calls
:func:`judge_imported` instead of training (:mod:`app.jobs.execute`). The stored ONNX file is
read back (checked against its hash) and through the gate again, the ``return`` and
``behaviour`` judges roll the policy out in a limited child process
(:func:`engine.policies.judging.imported_scores`: the same rollouts and scores as a
checkpoint's, cached under the runs dir by the policy's content hash, so the same file is
simulated once), each judge's Agent Preference Tree replays the advice bracket, and the report
is stored as the run's checkpoint artefact at its declared steps, with the checkpoint row: from
there the verdict, the experiment page and the compare page read it as any run's.

An imported policy has no shaped reward, shaping weight or critic, so the report holds the two
judges that read what a policy does, and its table's other columns are the candidate's stored
env reward (R, without a control cost) and zeros. Executor processes only: this loads torch
(with the report's types), MuJoCo and onnxruntime.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy.orm import Session, sessionmaker

from app.models import Run
from app.runs import artefacts, imported, run_state
from engine.errors import InputError
from engine.treefile import TreeDocument, replay, tree_from_json

if TYPE_CHECKING:  # loaded in the functions: torch and onnxruntime, executor processes only
    from engine.policies.onnx_policy import ImportedPolicy
    from engine.rl.report import CheckpointReport


def judge_imported(
    sessions: sessionmaker[Session],
    *,
    run_id: int,
    runs_root: Path,
    owner: tuple[Any, ...],
    should_stop: Callable[[], bool] = lambda: False,
) -> bool:
    """Judge imported run ``run_id`` and store its report and checkpoint.

    Args:
        sessions: database sessions.
        run_id: the run, claimed by the caller.
        runs_root: the runs dir, where the policy is stored.
        owner: the conditions under which the run is still the caller's.
        should_stop: asked once the policy is judged: True (a cancel, the run taken away)
            stores nothing, and the caller ends the run as its reason says.

    Returns:
        False when the run was no longer the caller's at the end (nothing more stored).

    Raises:
        InputError: the policy cannot be judged (a damaged file, a failure, or its child
            process ran out of memory or time); the run fails with the message.
    """
    with sessions() as session:
        run = session.get_one(Run, run_id)
        info, advice, pool, step = (
            imported.imported_of(run),
            run.advice,
            run.advice_pool,
            run.timesteps,
        )
    if info is None or advice is None:
        raise InputError(f"run {run_id} is not an imported policy with advice")
    with children_allowed():
        report = imported_report(
            load_policy(runs_root, info), tree_from_json(advice), step, runs_root
        )
    if should_stop():  # the rollouts cannot be interrupted; their result can be dropped
        return True
    body = artefacts.report_json(report, pool)
    with sessions() as session:
        artefacts.store(session, run_id=run_id, step=step, body=body)
    with sessions() as session:
        return run_state.record_update(
            session, run_id=run_id, owner=owner, row={"timesteps": step}, saved=True
        )


@contextmanager
def children_allowed() -> Iterator[None]:
    """Let this process start the judging child although it is daemonic.

    The local executor starts each run process as a daemon (multiprocessing stops it with its
    worker), and multiprocessing refuses a daemon children, lest they outlive it. The judging
    child cannot outlive it for long: the sandbox kills it at its time limit, and its CPU time
    is capped with ``RLIMIT_CPU`` should the run process die first.
    """
    config: dict[str, Any] = getattr(multiprocessing.current_process(), "_config", {})
    daemon = config.get("daemon")
    config["daemon"] = False
    try:
        yield
    finally:
        config["daemon"] = daemon


def load_policy(runs_root: Path, info: dict[str, Any]) -> ImportedPolicy:
    """The stored policy and its normalisation, checked again.

    Raises:
        InputError: a file is missing or damaged, or the model no longer passes the gate.
    """
    from engine.policies.normalisation import ObsNormalisation
    from engine.policies.onnx_check import check_onnx
    from engine.policies.onnx_policy import ImportedPolicy

    try:
        data = imported.read_blob(
            imported.onnx_file(runs_root, info["onnx_sha256"]), info["onnx_sha256"]
        )
        norm_digest = info.get("obs_norm_sha256")
        npz = None if norm_digest is None else imported.read_blob(
            imported.npz_file(runs_root, norm_digest), norm_digest
        )  # fmt: skip
    except OSError as exc:
        raise InputError(f"the imported policy's files cannot be read: {exc}") from exc
    obs_dim, act_dim = int(info["obs_dim"]), int(info["act_dim"])
    model = check_onnx(data, env_id=info["env_id"], obs_dim=obs_dim, act_dim=act_dim)
    norm = None if npz is None else ObsNormalisation.from_npz(npz, obs_dim=obs_dim)
    return ImportedPolicy(model, norm)


def imported_report(
    policy: ImportedPolicy, doc: TreeDocument, step: int, runs_root: Path
) -> CheckpointReport:
    """The policy's :class:`engine.rl.report.CheckpointReport` over ``doc``'s bracket, by the
    verdict judges (rollouts cached under :func:`app.runs.imported.policy_store`)."""
    from engine.conformance import compare
    from engine.judges import VERDICT_JUDGES
    from engine.policies.judging import imported_scores
    from engine.records import CandidateRow
    from engine.rl.report import CheckpointReport, JudgeResult
    from engine.tournament import ScoreJudge

    cache = imported.policy_store(runs_root)
    scores = {j: imported_scores(policy, doc, j, cache_dir=cache) for j in VERDICT_JUDGES}
    judges = {}
    for judge, by_id in scores.items():
        tree = replay(doc, ScoreJudge(by_id), f"agent:{judge}@{step}", scores=by_id)
        judges[judge] = JudgeResult(judge, tree, compare(doc, tree))
    rows = [
        CandidateRow(
            id=c.id,
            reward=c.env_reward,
            advice=0.0,
            z=0.0,
            shaping=0.0,
            shaped=c.env_reward,
            value=0.0,
            behaviour=scores["behaviour"][c.id],
            env_return=scores["return"][c.id],
        )
        for c in doc.candidates
    ]
    return CheckpointReport(step, judges, rows)
