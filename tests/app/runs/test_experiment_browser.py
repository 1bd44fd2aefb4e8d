"""The experiment page in a real browser (issue 25 §1): the runs by role while nothing is
judged, then the verdict once every run's checkpoint is, without a reload by the person.

The server's run worker is off: each run's checkpoint artefact is written into the server's
database as its executor would write it, with per-candidate scores whose truth is known
(advised runs follow the advice, the others go against it), so the verdict must say "used".
axe-core audits the page in both states, on a desktop and on a phone.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from playwright.sync_api import Browser, expect

from app.db import make_engine, make_sessions
from app.runs import artefacts
from tests.support.a11y import assert_accessible
from tests.support.artefacts import report_body
from tests.support.browser import ADMIN_TOKEN, DESKTOP, PHONE, new_page
from tests.support.labelling import wait_until_prepared
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env

pytestmark = pytest.mark.browser
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
STEP = 256


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """``acv serve`` without its run worker; yields ``(base URL, data dir)``."""
    data_dir = tmp_path_factory.mktemp("acv-experiment-data")
    env = clean_env(ACV_DATA_DIR=str(data_dir), ACV_ADMIN_TOKEN=ADMIN_TOKEN, ACV_RUN_WORKER="false")
    with acv_serve(env, data_dir / "server.log") as base:
        yield base, data_dir


def _judge_every_run(
    data_dir: Path, experiment: dict, advice: np.ndarray, step: int = STEP
) -> None:
    """Store each run's artefact at ``step`` in the server's SQLite database."""
    engine = make_engine(f"sqlite:///{data_dir / 'acv.sqlite3'}")
    rng = np.random.default_rng(1)
    try:
        with make_sessions(engine)() as session:
            for run in experiment["runs"]:
                sign = 1.0 if run["role"] == "advised" else -1.0
                body = report_body(step, sign * advice + rng.normal(0, 1e-3, advice.size))
                assert artefacts.store(session, run_id=run["id"], step=step, body=body)
    finally:
        engine.dispose()


def test_the_verdict_arrives_on_the_experiment_page(server, browser: Browser) -> None:
    base, data_dir = server
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        study = api.post(
            "/api/studies", json={"name": "exp", "env_id": "Hopper-v5", "n_candidates": 8}
        ).json()
        wait_until_prepared(api, study["id"])
        body = {"study_id": study["id"], "teacher": "good", "timesteps": 512, "n_envs": 1}
        experiment = api.post("/api/experiments", json=body | {"seeds": 5, "pilot_seeds": 1})
        assert experiment.status_code == 202, experiment.text
        experiment = experiment.json()
        candidates = api.get(f"/api/studies/{study['id']}/candidates").json()
    advice = np.array([c["env_reward"] for c in candidates])
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=DESKTOP)
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/experiments/{experiment['id']}?judge=behaviour")
    expect(page.locator("#experiment-runs tbody tr")).to_have_count(11)
    expect(page.locator("#verdict")).to_have_attribute("data-outcome", "pending")
    assert_accessible(page, "experiment page, nothing judged yet")
    _judge_every_run(data_dir, experiment, advice)
    # The page polls and shows the verdict by itself: interim while the runs have not ended
    # (no outcome word), then the verdict.
    expect(page.locator("#verdict")).to_have_attribute("data-outcome", "interim", timeout=30_000)
    expect(page.locator("#verdict")).to_contain_text("Interim: no verdict yet")
    assert_accessible(page, "experiment page with an interim look")
    _judge_every_run(data_dir, experiment, advice, step=2 * STEP)  # their last checkpoint
    expect(page.locator("#verdict")).to_have_attribute("data-outcome", "used", timeout=30_000)
    expect(page.locator("#verdict")).to_contain_text("used your advice")
    # With what the validation on known answers found of the judges (docs/validation.md).
    expect(page.locator("#judge-validation")).to_contain_text("no judge passed")
    assert_accessible(page, "experiment page with its verdict")
    # An advised run's comparison page gives the same verdict, for its judge.
    page.goto(f"{base}/runs/{experiment['runs'][0]['id']}/compare?judge=behaviour")
    note = page.locator(f"#experiment-note li[data-experiment='{experiment['id']}']")
    expect(note).to_have_attribute("data-outcome", "used")
    expect(note).to_contain_text("Used your advice")
    assert_accessible(page, "compare page with its experiment's verdict")
    context.close()
    phone, p = new_page(browser, errors, viewport=PHONE, is_mobile=True, has_touch=True)
    p.goto(f"{base}/login#token={ADMIN_TOKEN}")
    p.wait_for_url(f"{base}/studies")
    p.goto(f"{base}/experiments/{experiment['id']}?judge=shaped")
    expect(p.locator("#judge")).to_have_value("shaped")
    expect(p.locator("#verdict")).to_have_attribute("data-outcome", "diagnostic")
    assert_accessible(p, "experiment page on a phone, a diagnostic judge")
    phone.close()
    assert errors == []
