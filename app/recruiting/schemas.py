"""Bodies of the open-link API (issue 14), for studies and surveys alike."""

from __future__ import annotations

from typing import Annotated, TypeVar

from pydantic import BaseModel, ConfigDict, Field, StrictBool, field_validator

from app.core.json_types import JsonInt
from app.recruiting.links import (
    DEFAULT_EXTERNAL_PARAMS,
    MAX_PARTICIPANTS,
    MAX_TIME_LIMIT_MIN,
    REDIRECT_URL_PATTERN,
    LinkOptions,
)
from app.recruiting.seats import Ending, OutcomeName

Options = TypeVar("Options", bound=LinkOptions)
ParamName = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]{0,63}$")]


class OpenLinkIn(BaseModel):
    """An open link's options (a study's ``/s/<slug>``, a survey's ``/q/<slug>``)."""

    model_config = ConfigDict(extra="forbid")

    enabled: StrictBool = Field(description="Whether the open link admits visitors.")
    max_participants: JsonInt = Field(ge=1, le=MAX_PARTICIPANTS)
    external_params: list[ParamName] = Field(
        list(DEFAULT_EXTERNAL_PARAMS),
        min_length=1,
        max_length=10,
        description="Query parameters stored on the person; the first one identifies "
        "a returning person.",
    )
    consent_text: str | None = Field(None, min_length=1, max_length=20_000)
    completion_code: str | None = Field(
        None, min_length=1, max_length=100, description="The code of a member who finished."
    )
    decline_code: str | None = Field(
        None,
        min_length=1,
        max_length=100,
        description="The code of a visitor who declines consent or a member who withdraws.",
    )
    time_limit_min: JsonInt | None = Field(
        None,
        ge=1,
        le=MAX_TIME_LIMIT_MIN,
        description="Minutes a member has from joining to finishing; past it they are timed "
        "out (no code) and their seat is freed. Set it at or below the platform's own "
        "maximum time (null: no limit).",
    )
    redirect_url: str | None = Field(
        None,
        min_length=1,
        max_length=500,
        pattern=REDIRECT_URL_PATTERN,
        description="An http(s) URL to send people to when they end, with their outcome's "
        "code in place of {code} (e.g. https://app.prolific.com/submissions/complete?cc={code}).",
    )

    def options(self, kind: type[Options] = LinkOptions) -> Options:  # type: ignore[assignment]
        """The options the services take (``kind``: a subclass with a kind's own options)."""
        return kind(**{**self.model_dump(), "external_params": tuple(self.external_params)})


class SurveyCrowdOut(OpenLinkIn):
    """A survey's open link with its counts: respondents who joined through it, declined
    consents, and joined respondents who finished."""

    model_config = ConfigDict(from_attributes=True)

    survey_id: int
    slug: str
    url: str
    joined: int
    declines: int
    completed: int


class EvaluationCrowdOut(OpenLinkIn):
    """An evaluation's open link with its counts: evaluators who joined through it and
    declined consents."""

    model_config = ConfigDict(from_attributes=True)

    evaluation_id: int
    slug: str
    url: str
    joined: int
    declines: int


class WithdrawIn(BaseModel):
    """A member's explicit choice to withdraw (it cannot be undone)."""

    model_config = ConfigDict(extra="forbid")

    withdraw: StrictBool = Field(description="Must be true: withdrawing is final.")

    @field_validator("withdraw")
    @classmethod
    def _must_be_true(cls, value: bool) -> bool:
        if not value:
            raise ValueError("must be true to withdraw")
        return value


class OutcomeOut(BaseModel):
    """What became of a member, and the open link's code and way back for it."""

    outcome: OutcomeName
    code: str | None = Field(description="The code to give the platform (null: none).")
    redirect_url: str | None = Field(description="Where to go back to the platform, if set.")

    @classmethod
    def withdrawn(cls, shown: Ending | None) -> OutcomeOut:
        """A member who just withdrew, with the code and redirect ``shown`` for it."""
        return cls(
            outcome="withdrawn",
            code=shown.code if shown else None,
            redirect_url=shown.redirect_url if shown else None,
        )
