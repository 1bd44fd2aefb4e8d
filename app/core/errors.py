"""Service-layer failures that are not bad input; each maps to one HTTP status."""

from __future__ import annotations


class ServiceError(Exception):
    """Base class; ``status_code`` is the HTTP status the API answers with."""

    status_code = 400
    #: The heading of the HTML page that shows it (``None``: the status's phrase).
    title: str | None = None

    def __init__(self, detail: str):
        super().__init__(detail)
        self.detail = detail


class NotFoundError(ServiceError):
    """The object does not exist, or is not visible to the caller."""

    status_code = 404


class ConflictError(ServiceError):
    """The request contradicts the stored state (a match decided the other way, ...)."""

    status_code = 409


class AnsweredError(ConflictError):
    """Answered before with another choice (a second tab, the back button): the first
    answer is kept."""


class AuthError(ServiceError):
    """No valid credentials."""

    status_code = 401


class ForbiddenError(ServiceError):
    """Valid credentials that do not allow this."""

    status_code = 403


class TooManyAttemptsError(ServiceError):
    """Too many failed credentials from this address; try again in ``retry_after_s``."""

    status_code = 429

    def __init__(self, detail: str, *, retry_after_s: int):
        super().__init__(detail)
        self.retry_after_s = retry_after_s


class PendingError(ServiceError):
    """What was asked for is being computed elsewhere (a checkpoint's artefacts); ask again."""

    status_code = 202
