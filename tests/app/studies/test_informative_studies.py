"""``sampling: "informative"`` studies: refused (422) until a no-advice ppo run has finished
on the env, then sampled from that run's policy exactly as the engine does (issue 25 §5)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.settings import Settings
from engine.bracket import make_first_round
from engine.candidates import seed_abilities
from engine.informative import sample_informative
from engine.rl.checkpoint import find_checkpoint
from engine.rl.trained import deterministic_policy, load_agent
from tests.support.runs import TINY, create_run, run_app, wait_run
from tests.support.studies import new_study, wait_ready
from tests.support.web import ADMIN, ADMIN_TOKEN

pytestmark = [pytest.mark.training, pytest.mark.postgres_only]

BODY: dict[str, Any] = {
    "name": "informative",
    "env_id": "Hopper-v5",
    "n_candidates": 4,
    "p": 0.0,
    "seed": 7,
    "sampling": "informative",
    "instructions": "",
}
NO_BASELINE = (
    "informative sampling needs a finished no-advice ppo run on Hopper-v5; train one first"
)


@pytest.fixture(scope="module")
def client(settings: Settings) -> Iterator[TestClient]:
    with run_app(settings) as test_client:
        yield test_client


def test_the_study_form_says_why_before_any_baseline(client: TestClient) -> None:
    """Runs first in this module: its database has no run yet."""
    page = TestClient(client.app, follow_redirects=False)
    login = re.search(r'name="csrf_token" value="([^"]+)"', page.get("/login").text)
    assert login is not None
    page.post("/login", data={"csrf_token": login[1], "token": ADMIN_TOKEN})
    form = page.get("/studies/new").text
    assert '<option value="informative"' in form
    csrf = re.search(r'name="csrf_token" value="([^"]+)"', form)
    assert csrf is not None
    fields = {k: str(v) for k, v in BODY.items()} | {"csrf_token": csrf[1]}
    refused = page.post("/studies", data=fields)
    assert refused.status_code == 422 and NO_BASELINE in refused.text


def test_informative_study_waits_for_a_no_advice_baseline(
    client: TestClient, settings: Settings
) -> None:
    refused = client.post("/api/studies", json=BODY, headers=ADMIN)
    assert refused.status_code == 422
    assert refused.json() == {"detail": NO_BASELINE}

    host = new_study(client)  # a run belongs to a study; any study on the env will do
    advised = create_run(
        client, study_id=host["id"], algo="ppo-shaped", teacher="standing", timesteps=128, **TINY
    )
    assert wait_run(client, advised)["status"] == "succeeded"
    still = client.post("/api/studies", json=BODY, headers=ADMIN)
    assert still.status_code == 422 and still.json() == {"detail": NO_BASELINE}

    baseline = create_run(client, study_id=host["id"], algo="ppo", timesteps=256, **TINY)
    assert wait_run(client, baseline)["status"] == "succeeded"
    created = client.post("/api/studies", json=BODY, headers=ADMIN)
    assert created.status_code == 201, created.text
    study = wait_ready(client, created.json()["id"], timeout_s=120)
    assert study["status"] == "ready", study

    got = client.get(f"/api/studies/{study['id']}/candidates", headers=ADMIN).json()
    run_dir = settings.data_dir / "runs" / str(baseline)
    policy = deterministic_policy(load_agent(find_checkpoint(run_dir)))
    rng = np.random.default_rng(BODY["seed"])
    expected = sample_informative("Hopper-v5", 4, rng=rng, policy=policy)
    assert [c["qpos"] for c in got] == [e.qpos.tolist() for e in expected]  # exact floats
    assert len({tuple(c["qpos"]) for c in got}) == 4
    first = make_first_round([c.id for c in expected], seed_abilities(expected), 0.0, rng)
    invited = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    player = {"Authorization": f"Bearer {invited['token']}"}
    rounds = client.get("/api/participants/me/bracket", headers=player).json()["rounds"]
    assert [(c["a"], c["b"]) for c in rounds[0]] == first
    best_first = sorted(expected, key=lambda c: -float(c.seed_score or 0.0))
    assert first[0] == (best_first[0].id, best_first[-1].id)  # p = 0: best meets worst
