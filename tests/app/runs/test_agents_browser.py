"""Imported policies on the experiment and compare pages, in a real browser (issue 44 §2):
an external experiment's policies by arm with their declared training beside "ACV did not see
them train", then the verdict once they are judged, without a reload by the person; an
imported policy's comparison with the two judges it has. axe-core audits every state, on a
desktop and on a phone.

The server's run worker is off: each policy is judged here as a worker would judge it
(claimed, :func:`app.runs.imported_judge.judge_imported`, finished), with the judges' scores
replaced by ones whose truth is known (advised policies follow the advice, the others go
against it), so that the verdict must say "used" and no rollout is simulated (real judging:
tests/app/runs/test_agents_judged.py).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from playwright.sync_api import Browser, expect

import engine.policies.judging
from app.db import make_engine, make_sessions
from app.jobs import queue
from app.models import RunStatus
from app.runs.imported_judge import judge_imported
from engine.treefile import TreeDocument
from tests.support.a11y import assert_accessible
from tests.support.agents import DECLARED, policy
from tests.support.browser import ADMIN_TOKEN, DESKTOP, PHONE, new_page
from tests.support.labelling import wait_until_prepared
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env

pytestmark = pytest.mark.browser
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """``acv serve`` without its run worker; yields ``(base URL, data dir)``."""
    data_dir = tmp_path_factory.mktemp("acv-agents-data")
    env = clean_env(ACV_DATA_DIR=str(data_dir), ACV_ADMIN_TOKEN=ADMIN_TOKEN, ACV_RUN_WORKER="false")
    with acv_serve(env, data_dir / "server.log") as base:
        yield base, data_dir


def _import(api: httpx.Client, experiment: dict[str, Any]) -> list[dict[str, Any]]:
    """Five advised, five baseline and one pilot policy, uploaded as a researcher would."""
    tree = experiment["spec"]["tree_sha256"]
    arms = [("advised", s) for s in range(5)] + [("baseline", s) for s in range(5)]
    runs = []
    for i, (arm, seed) in enumerate([*arms, ("pilot", 1000)]):
        form = DECLARED | {"arm": arm, "seed": str(seed)}
        form |= {"tree_sha256": tree} if arm == "advised" else {}
        files = {"model": ("policy.onnx", policy(60 + i), "application/octet-stream")}
        response = api.post(f"/api/experiments/{experiment['id']}/agents", data=form, files=files)
        assert response.status_code == 202, response.text
        runs.append(response.json())
    return runs


def _judge_every_policy(
    data_dir: Path, runs: list[dict[str, Any]], monkeypatch: pytest.MonkeyPatch
) -> None:
    """What the worker does for each queued policy, the scores known (module docstring)."""
    sign = {run["id"]: 1.0 if run["imported"]["arm"] == "advised" else -1.0 for run in runs}
    rng = np.random.default_rng(1)
    current: dict[str, int] = {}

    def known_scores(policy: Any, doc: TreeDocument, judge: str, **_: Any) -> dict[int, float]:
        noise = rng.normal(0, 1e-3, len(doc.candidates))
        return {
            c.id: sign[current["run"]] * c.env_reward + e
            for c, e in zip(doc.candidates, noise, strict=True)
        }

    monkeypatch.setattr(engine.policies.judging, "imported_scores", known_scores)
    engine_ = make_engine(f"sqlite:///{data_dir / 'acv.sqlite3'}")
    sessions = make_sessions(engine_)
    try:
        for _ in runs:
            with sessions() as session:
                run_id = queue.claim_next(session, worker="test:1:x", executor="local")
            assert run_id is not None
            current["run"] = run_id
            owner = queue.ours(run_id, "test:1:x")
            assert judge_imported(sessions, run_id=run_id, runs_root=data_dir / "runs", owner=owner)
            with sessions() as session:
                done = RunStatus.SUCCEEDED
                assert queue.finish(session, run_id=run_id, worker="test:1:x", status=done)
    finally:
        engine_.dispose()


def test_imported_policies_on_the_experiment_and_compare_pages(
    server, browser: Browser, monkeypatch: pytest.MonkeyPatch
) -> None:
    base, data_dir = server
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        study = api.post(
            "/api/studies", json={"name": "agents", "env_id": "Hopper-v5", "n_candidates": 8}
        ).json()
        wait_until_prepared(api, study["id"])
        created = api.post(
            "/api/experiments/external", json={"study_id": study["id"], "teacher": "good"}
        )
        assert created.status_code == 201, created.text
        experiment = created.json()
        runs = _import(api, experiment)
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=DESKTOP)
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/experiments/{experiment['id']}?judge=behaviour")
    expect(page.locator("#experiment-runs tbody tr[data-imported]")).to_have_count(11)
    expect(page.locator("#verdict")).to_have_attribute("data-outcome", "pending")
    expect(page.locator("#experiment-runs")).to_contain_text("ACV did not see them train")
    expect(page.locator("#tree-sha256")).to_have_text(experiment["spec"]["tree_sha256"])
    expect(page.locator("#judge option")).to_have_count(2)  # the verdict judges only
    assert_accessible(page, "external experiment, nothing judged yet")
    _judge_every_policy(data_dir, runs, monkeypatch)
    # The page polls and shows the verdict by itself.
    expect(page.locator("#verdict")).to_have_attribute("data-outcome", "used", timeout=30_000)
    expect(page.locator("#experiment-runs tbody")).to_contain_text("imported, judged")
    assert_accessible(page, "external experiment with its verdict")
    advised = runs[0]["id"]
    page.goto(f"{base}/runs/{advised}/compare")
    expect(page.locator("#imported-policy")).to_contain_text("ACV did not see them train")
    expect(page.locator("#imported-policy")).to_contain_text("sb3 PPO, 100,000 steps, seed 0")
    expect(page.locator("#compare")).to_have_attribute("data-loaded", "100000:return")
    expect(page.locator("#candidates thead th")).to_have_count(4)  # no R, F, z, z F or V
    expect(page.locator("#candidates tbody tr")).to_have_count(8)
    expect(page.locator("#judges-body tr")).to_have_count(2)
    note = page.locator(f"#experiment-note li[data-experiment='{experiment['id']}']")
    expect(note).to_have_attribute("data-outcome", "used")
    assert_accessible(page, "an imported policy's comparison")
    context.close()
    phone, p = new_page(browser, errors, viewport=PHONE, is_mobile=True, has_touch=True)
    p.goto(f"{base}/login#token={ADMIN_TOKEN}")
    p.wait_for_url(f"{base}/studies")
    p.goto(f"{base}/experiments/{experiment['id']}")
    expect(p.locator("#verdict")).to_have_attribute("data-outcome", "used")
    assert_accessible(p, "external experiment on a phone")
    p.goto(f"{base}/runs/{advised}/compare?judge=behaviour")
    expect(p.locator("#compare")).to_have_attribute("data-loaded", "100000:behaviour")
    assert_accessible(p, "an imported policy's comparison on a phone")
    phone.close()
    assert errors == []
