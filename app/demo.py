"""The demo study that ``acv serve --demo`` (``make run``) starts with, and its experiment:
the simulated participant's advice trained on 5 seeds against a matched no-advice baseline,
queued for the server's run worker, so that the verdict arrives while the researcher looks
around (12 runs of 20k steps, about 7 minutes on two cores)."""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.labelling.participants import add_participants
from app.labelling.simulate import simulate
from app.models import Experiment, Label, Participant, Study, StudyStatus
from app.runs.experiments import ExperimentSpec, create_experiment
from app.runs.spec import RunSpec
from app.runtime import Runtime
from app.studies.service import StudySpec, create_study, get_study

DEMO_NAME = "Demo: upright humanoid"
DEMO_INSTRUCTIONS = (
    "You will see two pictures of a simulated humanoid robot at a time. Pick the posture you "
    "would rather the robot be in: click the picture, or press the left or right arrow key. "
    "Winners meet again in later rounds until one posture is left."
)
#: What the demo experiment trains: the tour's run (README), on 5 seeds with its baseline.
DEMO_RUN = {"algo": "bipars-em", "timesteps": 20_000}


@dataclass(frozen=True)
class Demo:
    """The demo study, a fresh participant's invite token, a simulated finished one, and the
    experiment on that one's advice."""

    study: Study
    invite_token: str
    simulated: Participant
    experiment_id: int


def ensure_demo(runtime: Runtime) -> Demo:
    """Create (once) and prepare the demo study: 16 Humanoid-v5 states, one participant
    already played by the ``standing`` teacher, and one invite nobody has used yet."""
    with runtime.sessions() as session:
        study = session.scalar(
            select(Study)
            .where(Study.name == DEMO_NAME, Study.status != StudyStatus.FAILED)
            .limit(1)
        )
        if study is None:
            spec = StudySpec(DEMO_NAME, "Humanoid-v5", 16, 0.9, 0, instructions=DEMO_INSTRUCTIONS)
            study = create_study(session, spec=spec)
    if study.status == StudyStatus.PREPARING:
        runtime.prepare(study.id)
    with runtime.sessions() as session:
        study = get_study(session, study_id=study.id)
        simulated = (
            _finished(session, study.id)
            or simulate(session, study_id=study.id, teacher="standing")[0]
        )
        experiment_id = _experiment(session, study.id, simulated.id)
        return Demo(study, _unused_invite(session, study.id), simulated, experiment_id)


def _experiment(session: Session, study_id: int, participant_id: int) -> int:
    """The demo study's experiment, queued on first use."""
    found = session.scalar(
        select(Experiment.id).where(Experiment.study_id == study_id).order_by(Experiment.id)
    )
    if found is not None:
        return found
    run = DEMO_RUN | {"study_id": study_id, "participant_id": participant_id}
    return create_experiment(session, spec=ExperimentSpec(run=RunSpec.from_request(run))).id


def _finished(session: Session, study_id: int) -> Participant | None:
    return session.scalar(
        select(Participant)
        .where(Participant.study_id == study_id, Participant.finished_at.is_not(None))
        .limit(1)
    )


def _unused_invite(session: Session, study_id: int) -> str:
    unused = session.scalar(
        select(Participant.token)
        .outerjoin(Label, Label.participant_id == Participant.id)
        .where(Participant.study_id == study_id, Participant.name.is_(None), Label.id.is_(None))
        .order_by(Participant.id)
        .limit(1)
    )
    return unused or add_participants(session, study_id=study_id)[0].token
