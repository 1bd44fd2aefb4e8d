"""Database tables (SQLAlchemy 2 declarative), one module per feature; the schema itself
comes from ``migrations/``. Everything is importable from ``app.models``, as before the split."""

from __future__ import annotations

from app.models.base import (
    NAMING,
    RUN_STATUSES,
    STUDY_STATUSES,
    Base,
    ExperimentRole,
    RunStatus,
    StudyStatus,
    as_utc,
    enum_type,
    status_check,
    utcnow,
)
from app.models.logins import LoginFailure
from app.models.people import (
    COLLECTION_KINDS,
    Member,
    OpenLink,
    token_digest,
)
from app.models.runs import (
    CheckpointArtefact,
    Experiment,
    ExperimentRun,
    Run,
    RunCheckpoint,
    RunMetric,
)
from app.models.studies import (
    BracketSlot,
    Candidate,
    ConsistencyCheck,
    CrowdSettings,
    DisagreementPair,
    GoldAnswer,
    GoldItem,
    Label,
    Match,
    Participant,
    Study,
)
from app.models.surveys import (
    SURVEY_ASSIGNMENTS,
    SURVEY_EXCLUSIONS,
    Survey,
    SurveyAnswer,
    SurveyCrowdSettings,
    SurveyRespondent,
    SurveyScreen,
    SurveyStimulus,
)
from app.models.webhooks import (
    Webhook,
    WebhookAttempt,
    WebhookEvent,
)

__all__ = [
    "COLLECTION_KINDS",
    "RUN_STATUSES",
    "STUDY_STATUSES",
    "Base",
    "BracketSlot",
    "Candidate",
    "CheckpointArtefact",
    "ConsistencyCheck",
    "CrowdSettings",
    "DisagreementPair",
    "Experiment",
    "ExperimentRole",
    "ExperimentRun",
    "GoldAnswer",
    "GoldItem",
    "Label",
    "LoginFailure",
    "Match",
    "Member",
    "NAMING",
    "OpenLink",
    "Participant",
    "Run",
    "RunCheckpoint",
    "RunMetric",
    "RunStatus",
    "SURVEY_ASSIGNMENTS",
    "SURVEY_EXCLUSIONS",
    "Study",
    "StudyStatus",
    "Survey",
    "SurveyAnswer",
    "SurveyCrowdSettings",
    "SurveyRespondent",
    "SurveyScreen",
    "SurveyStimulus",
    "Webhook",
    "WebhookAttempt",
    "WebhookEvent",
    "as_utc",
    "enum_type",
    "status_check",
    "token_digest",
    "utcnow",
]
