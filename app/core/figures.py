"""Static figures for exports and reports: Preference Trees and line charts (matplotlib).

A tree is drawn top-down like the pages draw it (``static/js/tree.js``): the champion at the
top, each node's children (the states it beat) below it in the file's order, thumbnails at
the nodes, the edge weight ``w`` on each edge, highlighted states in red. The layout is the
classic layered one: leaves left to right in depth-first order, each parent centred over its
children. SVG output embeds the thumbnails, so a file stands alone.
"""

from __future__ import annotations

import io
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PIL import Image

from engine.treefile import TreeDocument

if TYPE_CHECKING:
    from matplotlib.figure import Figure

log = logging.getLogger(__name__)
BAD, GOOD, EDGE, MUTED = "#c93c3c", "#1f8a4c", "#9aa5b4", "#5f6b7a"
FORMATS = {"svg": "image/svg+xml", "png": "image/png"}
_THUMB = 0.8  # thumbnail size in layout units (siblings are 1 apart)


@dataclass(frozen=True)
class Series:
    """One line of a chart: ``x`` and ``y`` of the same length (``y`` may hold NaN)."""

    label: str
    x: Sequence[float]
    y: Sequence[float]


def tree_layout(doc: TreeDocument) -> dict[int, tuple[float, int]]:
    """State id -> ``(x, depth - 1)``: leaves at 0, 1, 2, ... in depth-first order."""
    nodes, pos = doc.tree.nodes, {}
    next_leaf = [0.0]

    def place(state: int, level: int) -> float:
        kids = nodes[state].children
        if kids:
            xs = [place(k, level + 1) for k in kids]
            x = (xs[0] + xs[-1]) / 2
        else:
            x, next_leaf[0] = next_leaf[0], next_leaf[0] + 1
        pos[state] = (x, level)
        return x

    place(doc.tree.root, 0)
    return pos


def load_thumbs(paths: Mapping[int, Path]) -> dict[int, np.ndarray]:
    """Thumbnail images as RGB arrays. Missing or unreadable files (corrupt, truncated, not
    an image) are left out: their nodes are drawn without a picture rather than failing."""
    thumbs = {}
    for cid, path in paths.items():
        try:
            with Image.open(path) as img:
                thumbs[cid] = np.asarray(img.convert("RGB"))
        except (OSError, ValueError, Image.DecompressionBombError) as exc:
            log.warning("thumbnail of candidate %d left out (%s): %s", cid, path.name, exc)
    return thumbs


def tree_figure(
    doc: TreeDocument,
    *,
    thumbs: Mapping[int, np.ndarray] | None = None,
    highlight: frozenset[int] = frozenset(),
    title: str | None = None,
    fmt: str = "svg",
) -> bytes:
    """One Preference Tree as an SVG or PNG file."""
    width, levels = _extent(doc)
    fig = _figure(figsize=(max(4.0, 1.1 * width), 0.6 + 1.5 * levels))
    ax = fig.add_axes((0.01, 0.01, 0.98, 0.9 if title else 0.98))
    draw_tree(ax, doc, thumbs=thumbs, highlight=highlight)
    if title:
        fig.suptitle(title, fontsize=11)
    return _save(fig, fmt)


def trees_side_by_side(
    left: TreeDocument,
    right: TreeDocument,
    *,
    thumbs: Mapping[int, np.ndarray] | None = None,
    highlights: tuple[frozenset[int], frozenset[int]] = (frozenset(),) * 2,
    frame_colors: Mapping[int, str] | None = None,
    titles: tuple[str, str] = ("", ""),
    legend: Mapping[str, str] | None = None,
    title: str | None = None,
    fmt: str = "svg",
) -> bytes:
    """Two trees over one bracket in one figure, same layout rules (the paper's Figure 4).

    Args:
        frame_colors: state -> thumbnail frame colour (for example straight vs bent postures).
        legend: label -> colour, explaining ``frame_colors``.
    """
    width, levels = map(max, zip(_extent(left), _extent(right), strict=True))
    fig = _figure(figsize=(max(8.0, 2.2 * width), 1.0 + 1.5 * levels))
    for i, (doc, highlight, sub) in enumerate(zip((left, right), highlights, titles, strict=True)):
        ax = fig.add_axes((0.01 + 0.5 * i, 0.02, 0.48, 0.86 if title else 0.92))
        draw_tree(ax, doc, thumbs=thumbs, highlight=highlight, frame_colors=frame_colors)
        ax.set_title(sub, fontsize=10)
    if title:
        fig.suptitle(title, fontsize=12)
    if legend:
        from matplotlib.patches import Patch

        fig.legend(
            handles=[
                Patch(facecolor="white", edgecolor=c, linewidth=2, label=label)
                for label, c in legend.items()
            ],
            loc="lower center",
            ncols=len(legend),
            fontsize=8,
            frameon=False,
        )
    return _save(fig, fmt)


def _extent(
    doc: TreeDocument, pos: dict[int, tuple[float, int]] | None = None
) -> tuple[float, int]:
    """Width in leaves and depth in levels of a tree's layout."""
    pos = pos or tree_layout(doc)
    return max(x for x, _ in pos.values()) + 1, max(level for _, level in pos.values()) + 1


def draw_tree(
    ax,
    doc: TreeDocument,
    *,
    thumbs: Mapping[int, np.ndarray] | None = None,
    highlight: frozenset[int] = frozenset(),
    frame_colors: Mapping[int, str] | None = None,
) -> None:
    """Draw a tree on a matplotlib axis: highlighted states' edges and frames in red, unless
    ``frame_colors`` gives the frames' colours."""
    pos = tree_layout(doc)
    width, levels = _extent(doc, pos)
    for state, node in doc.tree.nodes.items():
        if node.parent is not None:
            _edge(ax, pos[node.parent], pos[state], node.weight, state in highlight)
    for state, node in doc.tree.nodes.items():
        color = BAD if state in highlight else GOOD if node.parent is None else EDGE
        if frame_colors is not None and state in frame_colors:
            color = frame_colors[state]
        _node(ax, pos[state], state, node.height, (thumbs or {}).get(state), color)
    ax.set_xlim(-0.6, width - 0.4)
    ax.set_ylim(-(levels - 1) * 1.5 - 0.75, 0.55)
    ax.set_aspect("equal")
    ax.axis("off")


def _edge(
    ax, parent: tuple[float, int], child: tuple[float, int], weight: int | None, bad: bool
) -> None:
    (x1, l1), (x2, l2) = parent, child
    y1, y2 = -l1 * 1.5 - _THUMB / 2 - 0.22, -l2 * 1.5 + _THUMB / 2
    ax.plot([x1, x2], [y1, y2], color=BAD if bad else EDGE, linewidth=2.5 if bad else 1.2, zorder=1)
    ax.text(
        (x1 + x2) / 2,
        (y1 + y2) / 2,
        f"w={weight}",
        fontsize=7,
        color=MUTED,
        ha="center",
        va="center",
        zorder=2,
        bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.5},
    )


def _node(
    ax, at: tuple[float, int], state: int, height: int, thumb: np.ndarray | None, color: str
) -> None:
    x, level = at
    y, half = -level * 1.5, _THUMB / 2
    if thumb is not None:
        ax.imshow(thumb, extent=(x - half, x + half, y - half, y + half), zorder=3)
    ax.add_patch(_frame(x, y, half, color))
    ax.text(
        x, y - half - 0.12, f"#{state} · h{height}", fontsize=7, ha="center", va="center", zorder=4
    )


def _frame(x: float, y: float, half: float, color: str):
    from matplotlib.patches import Rectangle

    return Rectangle(
        (x - half, y - half),
        2 * half,
        2 * half,
        fill=False,
        edgecolor=color,
        linewidth=2.5 if color != EDGE else 1.0,
        zorder=4,
    )


def line_chart(
    series: Sequence[Series],
    *,
    xlabel: str,
    ylabel: str,
    title: str,
    fmt: str = "svg",
    ylim: tuple[float, float] | None = None,
) -> bytes:
    """A small line chart of one or more series, with markers."""
    fig = _figure(figsize=(6.4, 3.2))
    ax = fig.subplots()
    for s in series:
        ax.plot(s.x, s.y, marker="o", markersize=3, linewidth=1.5, label=s.label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=11)
    if ylim is not None:
        ax.set_ylim(*ylim)
    ax.grid(alpha=0.3)
    if len(series) > 1:
        ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return _save(fig, fmt)


def _figure(figsize: tuple[float, float]) -> Figure:
    """A figure of the object API (no pyplot state, no display backend). matplotlib is imported
    here, not at the top: it costs a second, and the web process starts without it."""
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, dpi=100)


def _save(fig: Figure, fmt: str) -> bytes:
    if fmt not in FORMATS:
        raise ValueError(f"unknown figure format {fmt!r}")
    buffer = io.BytesIO()
    fig.savefig(buffer, format=fmt, metadata={"Date": None} if fmt == "svg" else None)
    return buffer.getvalue()
