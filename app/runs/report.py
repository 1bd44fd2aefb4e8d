"""What the comparison page, the exports and the self-contained HTML report show of a run.

The rejected advice (the human's matches the agent overturned) is highlighted in both trees:
in the Human Preference Tree the state the human ruled against (the edge of that match ends
there), in the Agent Preference Tree the state the human preferred and the agent ruled
against.
"""

from __future__ import annotations

import base64
import math
from pathlib import Path
from typing import Any, Literal

from jinja2 import Environment, FileSystemLoader, select_autoescape
from sqlalchemy.orm import Session

from app.core import figures
from app.core.resources import TEMPLATES_DIR
from app.models import Run
from app.runs import comparison, run_state
from app.runs.experiment_notes import notes_of_runs
from app.runs.imported_schemas import ImportedOut
from app.runs.service import advice_label, advice_of
from app.studies import service as studies
from app.studies.images import SPECS, image_file
from engine.conformance import Conformance
from engine.treefile import TreeDocument

REPORT_TEMPLATE = "compare_report.html"
_templates = Environment(
    loader=FileSystemLoader(TEMPLATES_DIR),
    autoescape=select_autoescape(),
    trim_blocks=True,
    lstrip_blocks=True,
)


def who(run: Run) -> str:
    """Who gave the advice, as the comparison speaks of them: ``you`` (the participant),
    ``the pool`` (pooled participants: their pooled verdict) or ``the standing teacher``."""
    if run.advice_pool:
        return "the pool"
    return "you" if run.participant_id is not None else f"the {run.teacher} teacher"


def whose(run: Run) -> str:
    """The possessive of :func:`who`: ``your``, ``the pool's`` or ``the standing teacher's``."""
    return "your" if run.participant_id is not None else f"{who(run)}'s"


def rejected_pairs(metrics: Conformance) -> list[dict[str, Any]]:
    """Each overturned match as ``{round, human, agent, other, contested}`` (``agent`` None
    for a tie)."""
    return [
        {
            "round": r.round,
            "human": r.human_winner,
            "agent": r.agent_winner,
            "other": r.b if r.human_winner == r.a else r.a,
            "contested": r.contested,
        }
        for r in metrics.rejected
    ]


def thumb_paths(session: Session, *, data_dir: Path, study_id: int) -> dict[int, Path]:
    """Candidate id -> its thumbnail file."""
    return {
        c.id: image_file(data_dir, c.thumb_path)
        for c in studies.list_candidates(session, study_id=study_id)
    }


def tree_file(
    doc: TreeDocument, *, thumbs: dict[int, Path], highlight: frozenset[int], title: str, fmt: str
) -> bytes:
    """A tree as an SVG or PNG file with thumbnails."""
    return figures.tree_figure(
        doc, thumbs=figures.load_thumbs(thumbs), highlight=highlight, title=title, fmt=fmt
    )


def tree_image(
    run: Run,
    view: comparison.CheckpointView,
    judge: str,
    which: Literal["human", "agent"],
    thumbs: dict[int, Path],
    fmt: str,
) -> bytes:
    """The run's advice tree (``human``) or ``judge``'s Agent Preference Tree at ``view``'s
    checkpoint (``agent``) as SVG or PNG with thumbnails, the rejected advice in red."""
    marked = comparison.highlights(view.of(judge))
    doc, title = (
        (advice_of(run), f"Human Preference Tree ({advice_label(run)})")
        if which == "human"
        else (view.tree(judge), f"Agent Preference Tree (step {view.step})")
    )
    return tree_file(doc, thumbs=thumbs, highlight=marked[which == "agent"], title=title, fmt=fmt)


def report_context(
    run: Run,
    *,
    session: Session,
    step: int,
    judge: str,
    thumbs: dict[int, Path],
    evaluations: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Everything ``compare_report.html`` shows; images inline, so the file stands alone.

    Raises:
        PendingError: the checkpoint's artefact is not computed yet.
    """
    view = comparison.checkpoint_view(session, run_id=run.id, step=step)
    metrics = view.of(judge)
    human, agent = (tree_image(run, view, judge, w, thumbs, "svg") for w in ("human", "agent"))
    curve = comparison.conformance_curve(session, run_id=run.id, judge=judge)
    return {
        "run": run,
        "advice": advice_label(run),
        "step": step,
        "judge": judge,
        "score_column": comparison.score_column(judge),
        "metrics": metrics,
        "verdict": comparison.verdict(view, judge, whose(run)),
        "experiment_notes": notes_of_runs(session, run_ids=[run.id], judge=judge),
        **(evaluations or {"evaluations": [], "tree_vs_asked": ""}),
        "who": who(run),
        "pairs": rejected_pairs(metrics),
        "judges": view.conformance,
        "candidates": view.candidates,
        "thumbs": {cid: data_uri(path) for cid, path in thumbs.items() if path.is_file()},
        "human_svg": inline_svg(human),
        "agent_svg": inline_svg(agent),
        "curve_svg": inline_svg(curve_chart(curve)),
        "learning_svg": inline_svg(learning_chart(run_state.metrics_rows(session, run_id=run.id))),
        "curve": curve,
        "imported": ImportedOut.of(run),
    }


def report_html(
    run: Run,
    *,
    session: Session,
    study_name: str,
    step: int,
    judge: str,
    thumbs: dict[int, Path],
    evaluations: dict[str, Any] | None = None,
) -> str:
    """The self-contained HTML report of a run at a checkpoint (no scripts, no links);
    ``evaluations``: the agent evaluations of its experiments, shown beside the tree verdict
    (``evaluations`` and ``tree_vs_asked``, from
    :func:`app.evaluations.results.notes_of_experiments`: a later feature, which the route
    asks)."""
    context = report_context(
        run, session=session, step=step, judge=judge, thumbs=thumbs, evaluations=evaluations
    )
    return _templates.get_template(REPORT_TEMPLATE).render(study_name=study_name, **context)


def curve_chart(curve: list[tuple[int, Conformance]], fmt: str = "svg") -> bytes:
    """Match agreement and Kendall tau-b over training."""
    steps = [step for step, _ in curve]
    tau = [math.nan if m.kendall_tau_b is None else m.kendall_tau_b for _, m in curve]
    return figures.line_chart(
        [
            figures.Series("match agreement", steps, [m.match_agreement for _, m in curve]),
            figures.Series("Kendall tau-b", steps, tau),
        ],
        xlabel="timesteps",
        ylabel="conformance",
        title="Conformance across training",
        fmt=fmt,
        ylim=(-1.05, 1.05),
    )


def learning_chart(rows: list[dict[str, Any]], fmt: str = "svg") -> bytes:
    """Mean true return of the last 100 episodes, and the mean shaping weight z."""
    steps = [row["timesteps"] for row in rows]

    def values(key: str) -> list[float]:
        return [math.nan if row.get(key) is None else row[key] for row in rows]

    return figures.line_chart(
        [
            figures.Series("return (last 100 episodes)", steps, values("return_100")),
            figures.Series("z (mean shaping weight)", steps, values("z_mean")),
        ],
        xlabel="timesteps",
        ylabel="value",
        title="Learning curve and z",
        fmt=fmt,
    )


def inline_svg(data: bytes) -> str:
    """An SVG file's ``<svg>`` element, to place inside HTML."""
    text = data.decode()
    return text[text.index("<svg") :]


def data_uri(path: Path) -> str:
    """A small image file as a ``data:`` URI."""
    encoded = base64.b64encode(path.read_bytes()).decode()
    return f"data:{SPECS['thumb'].media_type};base64,{encoded}"
