"""Publishing a written dataset folder (:mod:`app.labelling.dataset`) as a Hugging Face Hub
dataset repository, with ``huggingface_hub``.

The token is ``HF_TOKEN`` from the environment, never an option (a command line is seen by
every user of the machine). The Hub is ``HF_ENDPOINT`` when set, read at each push rather
than when ``huggingface_hub`` was imported.
"""

from __future__ import annotations

import os
from pathlib import Path

from app.core.errors import ServiceError
from engine.errors import InputError

TOKEN_VARIABLE = "HF_TOKEN"


class PushError(ServiceError):
    """The Hub refused the dataset or could not be reached."""

    status_code = 502


def check_repo(repo_id: str) -> str:
    """``repo_id`` if it is a Hub repository id (``user/name``).

    Raises:
        InputError: it is not.
    """
    from huggingface_hub.utils import HFValidationError, validate_repo_id

    try:
        validate_repo_id(repo_id)
    except HFValidationError as exc:
        raise InputError(f"--push-to-hub {repo_id[:100]!r}: {exc}") from None
    if "/" not in repo_id:
        raise InputError(f"--push-to-hub {repo_id[:100]!r}: name it as owner/name")
    return repo_id


def hub_token() -> str:
    """The Hub token from the environment.

    Raises:
        InputError: ``HF_TOKEN`` is not set.
    """
    token = os.environ.get(TOKEN_VARIABLE, "").strip()
    if not token:
        raise InputError(f"--push-to-hub needs a Hub token with write access in {TOKEN_VARIABLE}")
    return token


def push(folder: Path, *, repo_id: str, token: str, private: bool) -> str:
    """Create the dataset repository ``repo_id`` if it is new, then commit ``folder`` to it.

    Returns:
        The URL of the commit.

    Raises:
        PushError: the Hub answered with an error, or could not be reached.
    """
    from huggingface_hub import HfApi

    api = HfApi(endpoint=os.environ.get("HF_ENDPOINT") or None, token=token)
    try:
        api.create_repo(repo_id, repo_type="dataset", private=private, exist_ok=True)
        commit = api.upload_folder(
            folder_path=folder,
            repo_id=repo_id,
            repo_type="dataset",
            commit_message="Dataset exported by acv",
        )
    except Exception as exc:  # the network and the Hub's every answer: one clear line
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise PushError(f"could not push to the Hub dataset {repo_id}: {first}") from exc
    return str(commit.commit_url)
