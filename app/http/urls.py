"""URLs the API hands out: root-relative image URLs and absolute invite links."""

from __future__ import annotations

from fastapi import Request

from app.recruiting.members import STUDY, CollectionKind, MemberRow


def image_url(study_id: int, candidate_id: int, size: str = "full", marker: bool = False) -> str:
    """Where a candidate's image is served (see ``candidate_image``; ``size``: ``full`` or
    ``thumb``; ``marker``: with the instructed-response marker drawn on it)."""
    base = f"/api/studies/{study_id}/candidates/{candidate_id}/image"
    if marker:
        return f"{base}?marker=true" if size == "full" else f"{base}?size={size}&marker=true"
    return base if size == "full" else f"{base}?size={size}"


def clip_url(study_id: int, candidate_id: int) -> str:
    """Where a candidate's clip is served (see ``candidate_clip``), to whom its image is."""
    return f"/api/studies/{study_id}/candidates/{candidate_id}/clip"


def invite_url(request: Request, token: str) -> str:
    """The participant's invite link under the base URL this request came in on."""
    return member_invite_url(request, STUDY, token)


def member_invite_url(request: Request, kind: CollectionKind[MemberRow], token: str) -> str:
    """A member's invite link of ``kind`` under the base URL this request came in on."""
    return str(request.base_url).rstrip("/") + kind.invite_path(token)
