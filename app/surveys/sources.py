"""Where a survey's trees come from: a participant's Human Preference Tree, a run's Agent
Preference Tree at a checkpoint with a judge, or an uploaded ``acv.tree/1`` document.

Agent trees are never computed here (that needs torch and seconds of CPU): they are read from
the checkpoint's stored artefact (:class:`app.models.CheckpointArtefact`, written by the run
executor), and a checkpoint whose artefact is not stored yet is a 409 conflict.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, NotFoundError
from app.labelling.trees import participant_tree
from app.models import CheckpointArtefact, Participant, Run, Study, StudyStatus
from app.runs.artefacts import FAILURE, judged
from engine.conformance import compare
from engine.errors import InputError
from engine.judges import LEGACY_JUDGES, current_keys
from engine.treefile import TreeDocument, tree_from_json, tree_to_json

SourceKind = Literal["participant", "run", "upload"]
#: Checkpoints offered in the new-survey menu (the latest runs' latest first); any other is
#: still reachable through the API by run id and step.
MENU_CHECKPOINTS = 200


@dataclass(frozen=True)
class TreeSource:
    """One tree of a stimulus, as the researcher named it."""

    kind: SourceKind
    participant_id: int | None = None
    run_id: int | None = None
    checkpoint: int | None = None
    judge: str | None = None
    doc: dict[str, Any] | None = None
    study_id: int | None = None  # uploads: whose candidate images to draw, if any


@dataclass(frozen=True)
class ResolvedTree:
    """A tree ready to freeze into a stimulus."""

    doc: TreeDocument
    study_id: int | None
    source: dict[str, Any]


def resolve(session: Session, *, source: TreeSource) -> ResolvedTree:
    """The document a source names.

    Raises:
        NotFoundError: no such participant, run or study.
        ConflictError: the participant has not finished, or the checkpoint's agent trees are
            not computed yet.
        InputError: a judge the checkpoint has no tree for, or an invalid upload.
    """
    if source.kind == "participant":
        return _participant(session, source.participant_id)
    if source.kind == "run":
        return _run(session, source.run_id, source.checkpoint, source.judge)
    return _upload(session, source.doc, source.study_id)


def _participant(session: Session, participant_id: int | None) -> ResolvedTree:
    if participant_id is None:
        raise InputError("a participant tree needs participant_id")
    doc = participant_tree(session, participant_id=participant_id)
    study_id = session.get_one(Participant, participant_id).study_id  # participant_tree found it
    return ResolvedTree(doc, study_id, {"kind": "participant", "participant_id": participant_id})


def _run(session: Session, run_id: int | None, step: int | None, judge: str | None) -> ResolvedTree:
    if run_id is None or step is None or not judge:
        raise InputError("a run tree needs run_id, checkpoint and judge")
    run = session.get(Run, run_id)
    if run is None:
        raise NotFoundError(f"run {run_id} not found")
    artefact = session.get(CheckpointArtefact, (run_id, step))
    if artefact is None:
        raise ConflictError(
            f"the agent trees of run {run_id} at checkpoint {step} are not "
            "computed yet (or the run has no such checkpoint); try again "
            "when the run page lists the checkpoint as computed"
        )
    if not judged(artefact.payload):
        raise InputError(artefact.payload[FAILURE])
    judges = current_keys(artefact.payload.get("judges") or {})
    judge = LEGACY_JUDGES.get(judge, judge)
    if judge not in judges:
        raise InputError(
            f"run {run_id} at checkpoint {step} has no tree for judge {judge!r}; "
            f"it has: {', '.join(sorted(judges)) or 'none'}"
        )
    doc = tree_from_json(judges[judge].get("tree"))
    return ResolvedTree(
        doc, run.study_id, {"kind": "run", "run_id": run_id, "checkpoint": step, "judge": judge}
    )


def _upload(session: Session, obj: dict[str, Any] | None, study_id: int | None) -> ResolvedTree:
    if obj is None:
        raise InputError("an uploaded tree needs doc (an acv.tree/1 document)")
    _check_numbers(obj)
    doc = tree_from_json(obj)
    if study_id is not None:
        study = session.get(Study, study_id)
        if study is None:
            raise NotFoundError(f"study {study_id} not found")
        if study.n_candidates != len(doc.candidates) or study.env_id != doc.env_id:
            raise InputError(
                f"the uploaded tree ({len(doc.candidates)} {doc.env_id} "
                f"candidates) is not over study {study_id}'s candidates"
            )
    return ResolvedTree(doc, study_id, {"kind": "upload", "judge": doc.judge})


def _check_numbers(obj: dict[str, Any]) -> None:
    """Refuse an uploaded document's booleans and non-finite numbers, as a request body's
    number fields refuse them: the tree reader would take ``env_reward: true`` for 1.0. Its
    one flag, a match's ``tie``, may be true or false.

    Raises:
        InputError: names the first such value's place (``candidates[0].env_reward``).
    """
    stack: list[tuple[str, str, Any]] = [("", "", obj)]  # (place, key, value), iteratively
    while stack:
        place, key, value = stack.pop()
        if isinstance(value, bool) and key != "tie":
            flag = str(value).lower()
            raise InputError(f"'{place}' is {flag}: only a match's 'tie' may be a boolean")
        if isinstance(value, float) and not math.isfinite(value):
            raise InputError(f"'{place}' must be a finite number, got {value!r}")
        if isinstance(value, dict):
            dotted = f"{place}." if place else ""
            stack += [(f"{dotted}{k}", str(k), v) for k, v in reversed(value.items())]
        elif isinstance(value, list):
            stack += [(f"{place}[{i}]", "", v) for i, v in reversed(list(enumerate(value)))]


def highlights(tree1: TreeDocument, tree2: TreeDocument) -> tuple[list[int], list[int]]:
    """What the compare page marks: in Tree 1 the loser of each match Tree 2 decided the other
    way, in Tree 2 Tree 1's winner. Empty when the trees are over different brackets."""
    try:
        rejected = compare(tree1, tree2).rejected
    except InputError:
        return [], []
    first = sorted({r.b if r.human_winner == r.a else r.a for r in rejected})
    return first, sorted({r.human_winner for r in rejected})


def frozen(tree: ResolvedTree, *, name: str, highlight: list[int]) -> dict[str, Any]:
    """The JSON stored in a stimulus for one tree."""
    return {
        "name": name,
        "source": tree.source,
        "study_id": tree.study_id,
        "doc": tree_to_json(tree.doc),
        "highlight": highlight,
    }


def source_menus(session: Session) -> dict[str, list[dict[str, Any]]]:
    """What the new-survey page offers: finished participants and computed checkpoints."""
    people = session.execute(
        select(Participant.id, Participant.study_id, Participant.name, Study.name)
        .join(Study, Study.id == Participant.study_id)
        .where(Participant.finished_at.is_not(None))
        .order_by(Participant.id)
    )
    # Payloads hold whole trees: only the latest MENU_CHECKPOINTS are read for the menu.
    rows = session.execute(
        select(
            CheckpointArtefact.run_id, CheckpointArtefact.step, CheckpointArtefact.payload, Run.algo
        )
        .join(Run, Run.id == CheckpointArtefact.run_id)
        .order_by(CheckpointArtefact.run_id.desc(), CheckpointArtefact.step.desc())
        .limit(MENU_CHECKPOINTS)
    )
    return {
        "participants": [
            {"participant_id": pid, "study_id": sid, "name": name, "study": study}
            for pid, sid, name, study in people
        ],
        "checkpoints": [
            {
                "run_id": rid,
                "checkpoint": step,
                "algo": algo,
                "judges": sorted(current_keys((payload or {}).get("judges") or {})),
            }
            for rid, step, payload, algo in rows
            if judged(payload)
        ],
        "studies": [
            {"study_id": sid, "name": name}
            for sid, name in session.execute(
                select(Study.id, Study.name)
                .where(Study.status == StudyStatus.READY)
                .order_by(Study.id)
            )
        ],
    }
