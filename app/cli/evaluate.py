"""``acv evaluate``: agent evaluations (issue 41), the same service layer as
``/api/evaluations``: create one from an experiment or two groups of runs (its stills, and
clips, render here before the command returns), invite evaluators, read the answer."""

from __future__ import annotations

import json
import re
from typing import Annotated

import typer

from app.cli.options import JsonOpt, id_option
from app.cli.root import cli, fail
from app.cli.serve import cli_runtime
from app.evaluations import evaluators, results
from app.evaluations import service as evaluations
from app.models import StudyStatus
from app.recruiting.members import EVALUATION

Opt = typer.Option
evaluate_cli = typer.Typer(help="Agent evaluations: people judge what trained agents do.")
cli.add_typer(evaluate_cli, name="evaluate", no_args_is_help=True)


def _ids(text: str) -> tuple[int, ...]:
    """``"3,4,5"`` as run ids (exit 2 on anything else: digits only, so ``1_0``, which
    Python's ``int()`` reads as 10, is refused)."""
    parts = [part.strip() for part in text.split(",")]
    if not all(re.fullmatch(r"[0-9]+", part) for part in parts):
        fail(f"run ids are whole numbers separated by commas, got {text!r}")
    return tuple(int(part) for part in parts)


@evaluate_cli.command("create")
def create(
    experiment: Annotated[int | None, id_option("Evaluate this experiment's runs.")] = None,
    advised: Annotated[str | None, Opt(help="Or: advised run ids, e.g. 3,4,5.")] = None,
    baseline: Annotated[str | None, Opt(help="With --advised: baseline run ids.")] = None,
    kind: Annotated[str, Opt(help="Who answers: 'advisor' or 'others'.")] = "others",
    stimulus: Annotated[str, Opt(help="'clip' or 'still'.")] = "clip",
    show_bracket: Annotated[
        bool, Opt(help="Advisor only: remind them of their bracket with every pair.")
    ] = False,
    pairs: Annotated[int, Opt(help="Pairs per evaluator.")] = evaluations.DEFAULT_PAIRS,
    target: Annotated[float, Opt(help="Win rate the design is sized for.")] = (
        evaluations.DEFAULT_TARGET
    ),
    name: Annotated[str | None, Opt(help="A name for it.")] = None,
    gold_pairs: Annotated[
        int, Opt(help='Instructed gold pairs per evaluator ("choose the marker"), 0 to 5.')
    ] = 0,
    gold_gate: Annotated[
        float | None, Opt(help="With --gold-pairs: leave out evaluators clearly below it.")
    ] = None,
    practice_pairs: Annotated[int, Opt(help="Practice pairs first: 0, or 2 to 5.")] = 0,
) -> None:
    """Create an evaluation and render its stimuli; prints its id and status."""
    runs_named = [group is not None for group in (advised, baseline)]
    if any(runs_named) if experiment is not None else not all(runs_named):
        fail("give --experiment, or --advised with --baseline (not both)")
    if kind not in ("advisor", "others") or stimulus not in ("clip", "still"):
        fail("--kind is 'advisor' or 'others', --stimulus 'clip' or 'still'")
    with cli_runtime() as runtime:
        with runtime.sessions() as session:
            arms = (
                evaluations.experiment_arms(session, experiment_id=experiment)
                if experiment is not None
                else (_ids(advised), _ids(baseline))  # type: ignore[arg-type]  # both given
            )
            spec = evaluations.EvaluationSpec(
                advised=arms[0],
                baseline=arms[1],
                evaluator_kind=kind,  # type: ignore[arg-type]  # checked above
                show_bracket=show_bracket,
                stimulus=stimulus,  # type: ignore[arg-type]
                pairs_per_evaluator=pairs,
                target_win_rate=target,
                name=name,
                experiment_id=experiment,
                gold_pairs=gold_pairs,
                gold_gate=gold_gate,
                practice_pairs=practice_pairs,
            )
            evaluation_id = evaluations.create_evaluation(session, spec=spec).id
        runtime.prepare_evaluation(evaluation_id)
        with runtime.sessions() as session:
            found = evaluations.get_evaluation(session, evaluation_id=evaluation_id)
    typer.echo(f"evaluation {evaluation_id}: {found.status.value}")
    if found.status != StudyStatus.READY:
        fail(f"evaluation {evaluation_id} failed: {found.error}")


@evaluate_cli.command("invite")
def invite(
    evaluation: Annotated[int, id_option("Evaluation id.")],
    count: Annotated[int, Opt(help="How many evaluators to invite.")] = 1,
) -> None:
    """Invite evaluators; prints one invite link per line."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        people = evaluators.add_evaluators(session, evaluation_id=evaluation, count=count)
        base = (runtime.settings.public_url or "http://127.0.0.1:8000").rstrip("/")
        for person in people:
            typer.echo(base + EVALUATION.invite_path(person.token))


@evaluate_cli.command("result")
def result(
    evaluation: Annotated[int, id_option("Evaluation id.")], as_json: JsonOpt = False
) -> None:
    """The answer so far: the outcome in words (interim until the design's evaluators have
    finished), the statistic, its interval and p."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        found = results.result(session, evaluation_id=evaluation).to_json()
    if as_json:
        typer.echo(json.dumps(found, indent=2))
        return
    typer.echo(found["sentence"])
    keys = ("final", "finished_evaluators", "planned_evaluators")
    for key in ("statistic", "p_value", "interval", "n_answers", "n_evaluators", *keys):
        typer.echo(f"{key}\t{found.get(key)}")


@evaluate_cli.command("list")
def list_() -> None:
    """One line per evaluation: id, status, env, evaluator kind, stimulus, name."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        for e in evaluations.list_evaluations(session):
            typer.echo(
                f"{e.id}\t{e.status.value}\t{e.env_id}\t{e.evaluator_kind}\t{e.stimulus}\t{e.name}"
            )
