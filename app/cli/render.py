"""``acv render``: every candidate of a tree file as an image, ``<out>/<candidate id>.<ext>``."""

from __future__ import annotations

from pathlib import Path
from typing import cast

import typer
from tqdm import tqdm

from app.cli.root import cli, fail
from engine.errors import InputError
from engine.render import (
    DEFAULT_SIZE,
    DEFAULT_VIEW,
    MAX_SIZE,
    MIN_SIZE,
    VIEWS,
    BackendError,
    RenderService,
    RenderSpec,
    activate,
)
from engine.render.views import ImageFormat
from engine.treefile import load_tree


@cli.command("render")
def render_command(
    tree: Path = typer.Option(..., "--tree", help="An acv.tree/1 file (e.g. human.json)."),
    out: Path = typer.Option(..., "--out", help="Directory for the images (created)."),
    view: str = typer.Option(DEFAULT_VIEW, "--view", help=f"One of: {', '.join(VIEWS)}."),
    size: int = typer.Option(
        DEFAULT_SIZE, "--size", help=f"Pixels per side, {MIN_SIZE}..{MAX_SIZE}."
    ),
    fmt: str = typer.Option("jpg", "--format", help="jpg or png."),
    quality: bool = typer.Option(
        False, "--quality", help="Multisampling, shadows, reflections: for figures, slower."
    ),
) -> None:
    """Render every candidate state of TREE to OUT/<candidate id>.<format>."""
    try:
        # RenderSpec checks any spelling (jpeg, PNG) and normalises it to an ImageFormat.
        spec = RenderSpec(view=view, size=size, fmt=cast(ImageFormat, fmt), quality=quality)
        doc = load_tree(tree)
        activate()  # fail before any output when no OpenGL backend works
        out.mkdir(parents=True, exist_ok=True)
        with RenderService() as service:
            images = service.iter_render(
                doc.env_id, [(c.qpos, c.qvel) for c in doc.candidates], spec
            )
            progress = tqdm(images, total=len(doc.candidates), unit="img", desc="render")
            for candidate, data in zip(doc.candidates, progress, strict=True):
                (out / f"{candidate.id}.{spec.fmt}").write_bytes(data)
    except (InputError, BackendError) as exc:
        fail(str(exc))
    except OSError as exc:  # output directory not writable, a file in the way, ...
        fail(f"cannot write images to {out}: {exc}")
    typer.echo(
        f"wrote {len(doc.candidates)} {spec.fmt} images ({spec.view}, {spec.size} px) to {out}"
    )
