"""``acv export``: a study's labels as a dataset others can load (issue 29 §4), written as a
folder that ``datasets.load_dataset`` reads and, with ``--push-to-hub``, published on the
Hugging Face Hub (the token from ``HF_TOKEN``). Only participants who agreed to share are in
it, under pseudonyms (:mod:`app.labelling.dataset`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import typer

from app.cli.options import id_option
from app.cli.root import cli
from app.cli.serve import cli_runtime
from app.core.auth import dataset_salt
from app.labelling import dataset, dataset_hub
from app.labelling.dataset_card import DEFAULT_LICENSE


@cli.command("export")
def export(
    study: Annotated[int, id_option("Study id.")],
    out: Annotated[Path, typer.Option(help="A new (or empty) folder to write the dataset to.")],
    fmt: Annotated[
        Literal["hf"], typer.Option("--format", help="hf: a Hugging Face dataset folder.")
    ] = "hf",
    push_to_hub: Annotated[
        str | None,
        typer.Option(help="Also push it to this Hub dataset repository (owner/name)."),
    ] = None,
    private: Annotated[bool, typer.Option(help="Make a new Hub repository private.")] = False,
    license: Annotated[
        str, typer.Option(help="The dataset's licence, as the Hub names it.")
    ] = DEFAULT_LICENSE,
) -> None:
    """Write the study's labels, candidates, participants and trees as a dataset folder."""
    with cli_runtime() as runtime:
        token = None
        if push_to_hub is not None:  # refused before anything is written
            token = dataset_hub.hub_token()
            dataset_hub.check_repo(push_to_hub)
        settings = runtime.settings
        with runtime.sessions() as session:
            made = dataset.build(
                session,
                study_id=study,
                salt=dataset_salt(settings),
                data_dir=settings.data_dir,
                license=license,
            )
        dataset.write_folder(made, out)
        facts = made.facts
        typer.echo(
            f"wrote {out}: {facts.participants} participants, {facts.labels} labels, "
            f"{facts.trees} trees, {facts.n_candidates} candidates"
        )
        if push_to_hub is not None and token is not None:
            url = dataset_hub.push(out, repo_id=push_to_hub, token=token, private=private)
            typer.echo(f"pushed to {url}")
