"""Downloads: every file the app hands out as an attachment is answered the same way."""

from __future__ import annotations

from fastapi import Response


def attachment(content: bytes | str, media_type: str, filename: str) -> Response:
    """``content`` to be saved as ``filename``: never sniffed as another type, never cached
    (exports change as labels arrive)."""
    return Response(
        content,
        media_type=media_type,
        headers={
            "Content-Disposition": f'attachment; filename="{filename}"',
            "X-Content-Type-Options": "nosniff",
            "Cache-Control": "no-store",
        },
    )
