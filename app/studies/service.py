"""Studies: creation, preparation (sample, seed, render) and look-ups.

Creating a study stores its parameters with status ``preparing``; :func:`prepare_study`
(usually on a background thread) then samples the candidate states, seeds the first round
with the Braverman-Mossel model and renders the images, exactly as
:func:`engine.pipeline.run_tournament` does for the same seed, prepares its practice states
when it asks practice pairs (:mod:`app.studies.practice_states`), and sets ``ready``.

``informative`` sampling rolls out a trained no-advice baseline
(:mod:`app.studies.baseline`).
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import cast

import numpy as np
from sqlalchemy import select, update
from sqlalchemy.orm import Session, sessionmaker

from app.core.errors import ConflictError, NotFoundError
from app.core.limits import MAX_INSTRUCTIONS_CHARS, MAX_NAME_CHARS, MAX_SEED, check_text
from app.db import writing
from app.models import BracketSlot, Candidate, Study, StudyStatus
from app.studies.baseline import (
    baseline_returns,
    baseline_run,
    needs_baseline,
    no_baseline_message,
    study_baseline_id,
    study_policy,
)
from app.studies.clips import add_clips
from app.studies.images import ImageSize, render_candidates
from app.studies.practice_states import prepare_practice
from engine import candidates as engine_candidates
from engine.bracket import FirstRound, make_first_round
from engine.candidates import SamplingMode
from engine.disagreement import MAX_PAIRS
from engine.envs import check_env_id
from engine.errors import InputError
from engine.pipeline import sample_by_mode
from engine.practice import practice_pairs_error
from engine.render import RenderService

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StudySpec:
    """A study to create (``POST /api/studies``'s body, as the services take it)."""

    name: str
    env_id: str
    n_candidates: int
    p: float
    seed: int
    sampling: str = "uniform"
    instructions: str = ""
    disagreement_pairs: int = 0
    allow_ties: bool = False
    practice_pairs: int = 0
    clips: bool = False


def create_study(session: Session, *, spec: StudySpec) -> Study:
    """Validate and store a new study (status ``preparing``).

    Raises:
        InputError: any parameter is out of range, or the env is not a MuJoCo env.
    """
    _check_spec(session, spec)
    study = Study(**{**asdict(spec), "name": spec.name.strip(), "p": float(spec.p)})
    study.status = StudyStatus.PREPARING
    with writing(session):
        session.add(study)
    return study


def _check_spec(session: Session, spec: StudySpec) -> None:
    name, n, seed = spec.name, spec.n_candidates, spec.seed
    if not name.strip() or len(name) > MAX_NAME_CHARS:
        raise InputError(f"name must be 1..{MAX_NAME_CHARS} characters")
    check_text(name=name, instructions=spec.instructions, env_id=spec.env_id)
    if not 2 <= n <= engine_candidates.MAX_CANDIDATES:
        raise InputError(f"n_candidates must be in 2..{engine_candidates.MAX_CANDIDATES}, got {n}")
    if not 0.0 <= spec.p <= 1.0:
        raise InputError(f"p must be in [0, 1], got {spec.p}")
    if not 0 <= seed <= MAX_SEED:
        raise InputError(f"seed must be in 0..2**63-1, got {seed}")
    if spec.sampling not in engine_candidates.SAMPLING_MODES:
        raise InputError(
            f"sampling must be one of {', '.join(engine_candidates.SAMPLING_MODES)}"
            f", got {spec.sampling!r}"
        )
    if not 0 <= spec.disagreement_pairs <= MAX_PAIRS:
        raise InputError(
            f"disagreement_pairs must be in 0..{MAX_PAIRS}, got {spec.disagreement_pairs}"
        )
    if (practice := practice_pairs_error(spec.practice_pairs)) is not None:
        raise InputError(practice)
    if len(spec.instructions) > MAX_INSTRUCTIONS_CHARS:
        raise InputError(f"instructions must be at most {MAX_INSTRUCTIONS_CHARS} characters")
    _check_env(session, spec)


def _check_env(session: Session, spec: StudySpec) -> None:
    """The env can be made here, and a no-advice baseline exists where the study needs one."""
    env_id = spec.env_id
    try:
        check_env_id(env_id)
    except InputError:
        raise
    except Exception as exc:  # registered but unusable here (missing extras, ...)
        raise InputError(f"env {env_id!r} cannot be made: {type(exc).__name__}: {exc}") from exc
    needs = needs_baseline(sampling=spec.sampling, disagreement_pairs=spec.disagreement_pairs)
    if needs and baseline_run(session, env_id=env_id) is None:
        raise InputError(no_baseline_message(env_id, needs=needs))


def prepare_study(
    sessions: sessionmaker[Session],
    *,
    study_id: int,
    renderer: RenderService,
    data_dir: Path,
    runs_dir: Path | None = None,
) -> None:
    """Sample, seed and render a ``preparing`` study, mark it ``ready``, then render the
    clips of a study with clips (:mod:`app.studies.clips`: after ``ready``, never failing it).

    ``runs_dir`` holds the run directories (``data_dir / "runs"`` when None), where an
    ``informative`` study finds its baseline's checkpoint.

    Never raises: a failure is stored on the study (status ``failed``, ``error``) and logged.
    Safe to run twice at once (two server processes resuming the same study): the loser's
    inserts collide with the winner's, and a ``ready`` study is never marked ``failed``.
    """
    with sessions() as session:
        study = session.get(Study, study_id)
        baseline = None if study is None else study_baseline_id(session, study)
    if study is None or study.status != StudyStatus.PREPARING:
        return
    try:  # the slow part holds no database connection
        runs = runs_dir or data_dir / "runs"
        policy = study_policy(study, baseline, runs)
        cands, bracket = _sample(study, policy)
        returns = baseline_returns(study, baseline, cands, runs, policy)
        paths = render_candidates(
            renderer, data_dir=data_dir, env_id=study.env_id, candidates=cands
        )
        assert renderer.cache is not None  # render_candidates refused a renderer without one
        prepare_practice(
            renderer, images_dir=renderer.cache.root, study=study, exclude=[c.qpos for c in cands]
        )
        with sessions() as session:
            _store(session, study_id, cands, bracket, paths, returns)
    except Exception as exc:  # any failure must end up on the study, not in a thread's log
        log.exception("preparing study %d failed", study_id)
        with sessions() as session, writing(session):  # unless another process finished it
            session.execute(
                update(Study)
                .where(Study.id == study_id, Study.status == StudyStatus.PREPARING)
                .values(
                    status=StudyStatus.FAILED, error=f"{type(exc).__name__}: {exc}".splitlines()[0]
                )
            )
        return
    add_clips(sessions, study_id=study_id, renderer=renderer, data_dir=data_dir, runs_dir=runs)


def _sample(
    study: Study, policy: engine_candidates.Policy | None
) -> tuple[list[engine_candidates.Candidate], FirstRound]:
    """Candidates, then the first round, from one generator (as ``run_tournament`` does)."""
    rng = np.random.default_rng(study.seed)
    cands = sample_by_mode(
        study.env_id,
        study.n_candidates,
        rng=rng,
        mode=cast(SamplingMode, study.sampling),
        policy=policy,
    )
    abilities = engine_candidates.seed_abilities(cands)
    return cands, make_first_round([c.id for c in cands], abilities, study.p, rng)


def _store(
    session: Session,
    study_id: int,
    cands: list[engine_candidates.Candidate],
    bracket: FirstRound,
    paths: list[dict[ImageSize, str]],
    returns: list[float] | None,
) -> None:
    with writing(session):
        session.add_all(
            Candidate(
                study_id=study_id,
                id=c.id,
                qpos=c.qpos.tolist(),
                qvel=c.qvel.tolist(),
                env_reward=float(c.env_reward),
                image_path=path["full"],
                thumb_path=path["thumb"],
                baseline_return=ret,
            )
            for c, path, ret in zip(cands, paths, _or_nones(returns, len(cands)), strict=True)
        )
        session.flush()  # candidates before the slots that reference them
        session.add_all(
            BracketSlot(study_id=study_id, slot=k, a=a, b=b) for k, (a, b) in enumerate(bracket)
        )
        session.execute(update(Study).where(Study.id == study_id).values(status=StudyStatus.READY))


def _or_nones(values: list[float] | None, n: int) -> list[float | None]:
    return [None] * n if values is None else list(values)


def list_studies(session: Session) -> list[Study]:
    """All studies, newest first."""
    return list(session.scalars(select(Study).order_by(Study.id.desc())))


def get_study(session: Session, *, study_id: int) -> Study:
    """The study, or :class:`NotFoundError`."""
    study = session.get(Study, study_id)
    if study is None:
        raise NotFoundError(f"study {study_id} not found")
    return study


def get_ready_study(session: Session, *, study_id: int) -> Study:
    """The study if its candidates and bracket exist; :class:`ConflictError` otherwise."""
    study = get_study(session, study_id=study_id)
    if study.status != StudyStatus.READY:
        raise ConflictError(
            f"study {study_id} is {study.status}, not ready"
            + (f": {study.error}" if study.error else "")
        )
    return study


def list_candidates(session: Session, *, study_id: int) -> list[Candidate]:
    """The study's candidates in id order (empty while it is preparing)."""
    get_study(session, study_id=study_id)
    return list(
        session.scalars(
            select(Candidate).where(Candidate.study_id == study_id).order_by(Candidate.id)
        )
    )


def get_candidate(session: Session, *, study_id: int, candidate_id: int) -> Candidate:
    """One candidate, or :class:`NotFoundError`."""
    cand = session.get(Candidate, (study_id, candidate_id))
    if cand is None:
        raise NotFoundError(f"candidate {candidate_id} of study {study_id} not found")
    return cand


def first_round(session: Session, *, study_id: int) -> FirstRound:
    """The study's first round in bracket order, ``(a, None)`` for a bye."""
    rows = session.execute(
        select(BracketSlot.a, BracketSlot.b)
        .where(BracketSlot.study_id == study_id)
        .order_by(BracketSlot.slot)
    )
    return [(a, b) for a, b in rows]


def engine_candidates_of(session: Session, *, study_id: int) -> list[engine_candidates.Candidate]:
    """The study's candidates as engine objects (float64 arrays), ids ``0 .. N-1``."""
    return [
        engine_candidates.Candidate(
            c.id,
            np.asarray(c.qpos, dtype=np.float64),
            np.asarray(c.qvel, dtype=np.float64),
            c.env_reward,
        )
        for c in list_candidates(session, study_id=study_id)
    ]


def preparing_study_ids(session: Session) -> list[int]:
    """Studies left ``preparing`` (e.g. by a restart), to prepare again."""
    return list(session.scalars(select(Study.id).where(Study.status == StudyStatus.PREPARING)))
