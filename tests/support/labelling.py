"""Studies and brackets through the REST API, for tests that need them ready or labelled."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import httpx
import pytest

from tests.support.runs import FINAL, TINY
from tests.support.wait import wait_for

Match = dict[str, Any]
MAX_MATCHES = 64  # a bracket of N candidates has N - 1 matches; no test study is larger


def wait_until_prepared(api: httpx.Client, study_id: int, timeout_s: float = 180) -> dict:
    """Wait until the study has left ``preparing``; asserts it is ``ready`` and returns it."""
    study = wait_for(
        lambda: api.get(f"/api/studies/{study_id}").json(),
        lambda got: got["status"] != "preparing",
        what=f"study {study_id} to be prepared",
        timeout_s=timeout_s,
    )
    assert study["status"] == "ready", study
    return study


def label_bracket(
    client: httpx.Client, token: str, pick: Callable[[Match], int], response_ms: int | None = None
) -> None:
    """Decide every match of the participant with invite ``token``: the winner is
    ``pick(match)`` (a next-match body). Fails the test on a label that is not stored."""
    me = {"Authorization": f"Bearer {token}"}
    extra = {} if response_ms is None else {"response_ms": response_ms}
    for _ in range(MAX_MATCHES):
        match = client.get("/api/participants/me/next-match", headers=me)
        if match.status_code == 204:
            return
        assert match.status_code == 200, match.text
        body = match.json()
        label = client.post(
            f"/api/matches/{body['match_id']}/label",
            headers=me,
            json={"winner": pick(body), **extra},
        )
        assert label.status_code == 201, label.text
    pytest.fail(f"the participant still had matches after {MAX_MATCHES} labels")


def served_baseline(api: httpx.Client) -> None:
    """A finished tiny no-advice ``ppo`` run on Hopper of a 4-candidate host study, made over
    a served app's API: the baseline that disagreement pairs and candidate clips need."""
    host = api.post("/api/studies", json={"name": "host", "env_id": "Hopper-v5", "n_candidates": 4})
    wait_until_prepared(api, host.json()["id"])
    run = api.post(
        "/api/runs", json={"study_id": host.json()["id"], "algo": "ppo", "timesteps": 256, **TINY}
    )
    assert run.status_code == 202, run.text
    done = wait_for(
        lambda: api.get(f"/api/runs/{run.json()['id']}").json(),
        lambda got: got["status"] in FINAL,
        what="the baseline run to end",
        timeout_s=180,
    )
    assert done["status"] == "succeeded", done
