"""``/api/runs/{id}/clip``: a short clip of what a run's latest checkpoint does (issue 41 §3),
for researchers; the run and compare pages load it lazily (``static/js/run_clip.js``).

The first request queues the rendering on the runtime's background worker and answers 202
``{"status": "rendering"}`` with ``Retry-After``; once the file exists, 200 with the
animated WebP (``/clip``) or its still, a JPEG (``/clip/still``: what a paused clip shows).
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response
from fastapi.responses import FileResponse, JSONResponse

from app.evaluations.stimuli import STILLS, stimuli_dir
from app.http.deps import DbId, ResearcherDep, RuntimeDep, SessionDep
from app.jobs.settings import JobSettings
from app.runs import clips

router = APIRouter(prefix="/runs", tags=["runs"])
#: Seconds a client should wait before asking again while the clip renders.
RETRY_AFTER_S = 2
RENDERING: dict[int | str, dict[str, Any]] = {
    202: {"description": 'Rendering: {"status": "rendering"}; ask again after Retry-After.'},
    404: {"description": "No such run, or it has saved no checkpoint."},
    409: {"description": "Rendering the clip failed."},
}
MEDIA = {"clip": "image/webp", "still": "image/jpeg"}


def _answer(
    request: Request, runtime: RuntimeDep, session: SessionDep, run_id: int, part: clips.Part
) -> Response:
    """The stored file, or 202 after queueing its rendering (once per clip at a time)."""
    jobs: JobSettings = getattr(request.app.state, "job_settings", None) or JobSettings()
    out = stimuli_dir(runtime.settings.data_dir)
    source = clips.clip_source(
        session, run_id=run_id, runs_dir=jobs.runs_root(runtime.settings), options=STILLS
    )
    found = clips.stored_or_queued(
        source, out, part, options=STILLS, renderer=runtime.renderer, submit=runtime.submit
    )
    if found is not None:
        return FileResponse(
            found, media_type=MEDIA[part], headers={"Cache-Control": "private, max-age=3600"}
        )
    return JSONResponse(
        {"status": "rendering"}, status_code=202, headers={"Retry-After": str(RETRY_AFTER_S)}
    )


@router.get("/{run_id}/clip", response_class=Response, responses=RENDERING)
def run_clip(
    run_id: DbId, request: Request, runtime: RuntimeDep, session: SessionDep, _: ResearcherDep
) -> Response:
    """A 2 s clip (animated WebP) of the first stimulus window of the run's latest
    checkpoint; 202 while it renders."""
    return _answer(request, runtime, session, run_id, "clip")


@router.get("/{run_id}/clip/still", response_class=Response, responses=RENDERING)
def run_clip_still(
    run_id: DbId, request: Request, runtime: RuntimeDep, session: SessionDep, _: ResearcherDep
) -> Response:
    """The clip's still (JPEG, its middle frame): what a paused clip shows; 202 while the
    clip renders."""
    return _answer(request, runtime, session, run_id, "still")
