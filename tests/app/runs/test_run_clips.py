"""A run's clip (issue 41 §3) and its experiment's agent evaluations beside the tree verdict
(§2 "Where").

Through the API, on both databases: the first ask answers 202 and queues the rendering, then
200 with an animated WebP (and its still), 404 for a run without a checkpoint, 401 without
the researcher's credentials; the compare page and the report show the experiment's
evaluations with the sentence on how "followed your tree" and "does what you asked" differ.

In a real browser: the run page loads its clip only once scrolled into view, pauses it to
its still, and with reduced motion shows the still until Play; the compare page shows the
clip and the evaluation's sentence; axe-core audits each state.

The runs never train: each advised and baseline run gets a real (untrained) checkpoint.
"""

from __future__ import annotations

import io
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from PIL import Image
from playwright.sync_api import Browser, Page, expect

from app.evaluations.results import TREE_VS_ASKED, notes_of_experiments
from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN, new_page, wait_until_still
from tests.support.evaluations import (
    EXPERIMENT,
    evaluable_experiment,
    save_served_checkpoints,
)
from tests.support.labelling import wait_until_prepared
from tests.support.runs import run_app
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env
from tests.support.studies import new_study
from tests.support.wait import wait_for
from tests.support.web import ADMIN, logged_in

# postgres_only: rendering clips is the subject, not storage.
pytestmark = pytest.mark.postgres_only

#: Rolling out and rendering one clip: seconds, minutes on a loaded 2-core machine.
RENDER_S = 300
BROWSER_ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def experiment(client: TestClient) -> dict[str, Any]:
    study = new_study(client, n_candidates=5, seed=23)
    return evaluable_experiment(client, study["id"], seeds=2)


def _role(experiment: dict[str, Any], role: str) -> int:
    return next(r["id"] for r in experiment["runs"] if r["role"] == role)


def test_a_clip_renders_once_then_is_served(client, experiment) -> None:
    run_id = _role(experiment, "advised")
    first = client.get(f"/api/runs/{run_id}/clip", headers=ADMIN)
    assert first.status_code == 202, first.text
    assert first.json() == {"status": "rendering"} and int(first.headers["Retry-After"]) > 0
    again = client.get(f"/api/runs/{run_id}/clip/still", headers=ADMIN)
    assert again.status_code in (200, 202)  # queued once: the claim holds until it is done

    response = wait_for(
        lambda: client.get(f"/api/runs/{run_id}/clip", headers=ADMIN),
        lambda r: r.status_code != 202,
        what=f"the clip of run {run_id}",
        timeout_s=RENDER_S,
        every_s=0.5,
    )
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "image/webp"
    with Image.open(io.BytesIO(response.content)) as clip:
        assert clip.format == "WEBP" and clip.is_animated and clip.n_frames > 1
    still = client.get(f"/api/runs/{run_id}/clip/still", headers=ADMIN)
    assert still.status_code == 200 and still.headers["content-type"] == "image/jpeg"
    with Image.open(io.BytesIO(still.content)) as picture:
        assert picture.format == "JPEG"


def test_a_run_without_checkpoint_has_no_clip(client, experiment) -> None:
    pilot = _role(experiment, "pilot")
    response = client.get(f"/api/runs/{pilot}/clip", headers=ADMIN)
    assert response.status_code == 404, response.text
    assert "checkpoint" in response.json()["detail"]
    assert client.get("/api/runs/987654/clip", headers=ADMIN).status_code == 404
    assert client.get("/api/runs/0/clip", headers=ADMIN).status_code == 422


def test_only_a_researcher_sees_a_clip(client, experiment) -> None:
    run_id = _role(experiment, "advised")
    assert client.get(f"/api/runs/{run_id}/clip").status_code == 401
    wrong = {"Authorization": "Bearer not-the-token"}
    assert client.get(f"/api/runs/{run_id}/clip/still", headers=wrong).status_code == 401


def test_the_compare_page_and_report_show_the_evaluations(client, experiment) -> None:
    body = {"pairs_per_evaluator": 6, "stimulus": "still"}
    made = client.post(f"/api/experiments/{experiment['id']}/evaluations", json=body, headers=ADMIN)
    assert made.status_code == 201, made.text
    evaluation_id = made.json()["id"]
    sentence = client.get(f"/api/evaluations/{evaluation_id}/result", headers=ADMIN).json()[
        "sentence"
    ]
    run_id = _role(experiment, "advised")
    researcher = logged_in(client)
    page = researcher.get(f"/runs/{run_id}/compare")
    assert page.status_code == 200, page.text
    assert f'href="/evaluations/{evaluation_id}"' in page.text
    assert _plain(sentence) in _plain(page.text)
    assert _plain(TREE_VS_ASKED) in _plain(page.text)
    assert f'alt="What run {run_id} does: a 2 s clip of its latest checkpoint"' in page.text
    runs_page = researcher.get(f"/runs/{run_id}/compare-runs")
    assert f'href="/evaluations/{evaluation_id}"' in runs_page.text
    # the report (judged checkpoints only, so asked here directly) is handed the same notes
    with client.app.state.runtime.sessions() as session:
        notes = notes_of_experiments(session, [experiment["id"]])
    assert notes["tree_vs_asked"] == TREE_VS_ASKED
    assert [(e["id"], e["sentence"]) for e in notes["evaluations"]] == [(evaluation_id, sentence)]


def _plain(html: str) -> str:
    """Text with its whitespace collapsed and quotes as Jinja escapes them."""
    return re.sub(r"\s+", " ", html.replace("&#34;", '"').replace("&#39;", "'"))


# --- in a browser ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """``acv serve`` without its run worker; yields ``(base URL, data dir)``."""
    data_dir = tmp_path_factory.mktemp("acv-clip-data")
    env = clean_env(ACV_DATA_DIR=str(data_dir), ACV_ADMIN_TOKEN=ADMIN_TOKEN, ACV_RUN_WORKER="false")
    with acv_serve(env, data_dir / "server.log") as base:
        yield base, data_dir


@pytest.fixture(scope="module")
def served(server: tuple[str, Path]) -> dict[str, Any]:
    """An experiment on the server (2 seeds) whose advised and baseline runs saved a
    checkpoint."""
    base, data_dir = server
    with httpx.Client(base_url=base, headers=BROWSER_ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        body = {"name": "Clip study", "env_id": "Hopper-v5", "n_candidates": 5, "seed": 6}
        study = api.post("/api/studies", json=body)
        wait_until_prepared(api, study.json()["id"])
        made = api.post(
            "/api/experiments",
            json={"study_id": study.json()["id"], "teacher": "good", "seeds": 2, **EXPERIMENT},
        )
        assert made.status_code == 202, made.text
    save_served_checkpoints(data_dir, made.json())
    return made.json()


def _login(page: Page, base: str) -> None:
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")


def _audited(page: Page, what: str) -> None:
    wait_until_still(page)
    assert_accessible(page, what)


@pytest.mark.browser
def test_the_run_page_loads_its_clip_lazily_and_pauses_it(
    server, served, browser: Browser, screens: Path
) -> None:
    base, _ = server
    run_id = _role(served, "advised")
    errors: list[str] = []
    _, page = new_page(browser, errors, viewport={"width": 1000, "height": 600})
    asked: list[str] = []
    page.on("request", lambda r: asked.append(r.url) if "/clip" in r.url else None)
    _login(page, base)
    page.goto(f"{base}/runs/{run_id}")
    figure = page.locator("#run-clip")
    expect(figure).to_have_attribute("data-state", "waiting")
    _audited(page, "run page, clip not in view")
    assert asked == []  # nothing asked for before it scrolls into view

    figure.scroll_into_view_if_needed()
    expect(figure).to_have_attribute("data-state", "playing", timeout=RENDER_S * 1000)
    img = page.locator("#run-clip .run-clip-img")
    expect(img).to_have_attribute("src", f"/api/runs/{run_id}/clip")
    expect(img).to_have_attribute(
        "alt", f"What run {run_id} does: a 2 s clip of its latest checkpoint"
    )
    assert page.evaluate("document.querySelector('#run-clip img').naturalWidth") > 0
    _audited(page, "run page, clip playing")
    page.screenshot(path=screens / "run-clip-playing.png", full_page=True)

    toggle = page.locator("#run-clip .run-clip-toggle")
    expect(toggle).to_have_text("Pause")
    toggle.click()
    expect(figure).to_have_attribute("data-state", "paused")
    expect(img).to_have_attribute("src", f"/api/runs/{run_id}/clip/still")
    expect(toggle).to_have_text("Play")
    _audited(page, "run page, clip paused")
    toggle.click()
    expect(figure).to_have_attribute("data-state", "playing")
    assert errors == []


@pytest.mark.browser
def test_reduced_motion_shows_the_still_until_play(server, served, browser: Browser) -> None:
    base, _ = server
    run_id = _role(served, "advised")
    errors: list[str] = []
    _, page = new_page(browser, errors, reduced_motion="reduce")
    _login(page, base)
    page.goto(f"{base}/runs/{run_id}")
    figure = page.locator("#run-clip")
    figure.scroll_into_view_if_needed()
    expect(figure).to_have_attribute("data-state", "paused", timeout=RENDER_S * 1000)
    img = page.locator("#run-clip .run-clip-img")
    expect(img).to_have_attribute("src", f"/api/runs/{run_id}/clip/still")
    _audited(page, "run page, reduced motion")
    page.locator("#run-clip .run-clip-toggle").click()
    expect(figure).to_have_attribute("data-state", "playing")
    assert errors == []


@pytest.mark.browser
def test_the_compare_page_shows_the_clip_and_the_evaluation(
    server, served, browser: Browser, screens: Path
) -> None:
    base, _ = server
    run_id = _role(served, "advised")
    with httpx.Client(base_url=base, headers=BROWSER_ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        made = api.post(
            f"/api/experiments/{served['id']}/evaluations",
            json={"pairs_per_evaluator": 6, "stimulus": "still"},
        )
        assert made.status_code == 201, made.text
        evaluation_id = made.json()["id"]
        sentence = api.get(f"/api/evaluations/{evaluation_id}/result").json()["sentence"]
    errors: list[str] = []
    _, page = new_page(browser, errors)
    _login(page, base)
    page.goto(f"{base}/runs/{run_id}/compare")
    note = page.locator(f'#experiment-evaluations li[data-evaluation="{evaluation_id}"]')
    expect(note).to_contain_text(sentence)
    expect(note.locator("a")).to_have_attribute("href", f"/evaluations/{evaluation_id}")
    expect(page.locator("#tree-vs-asked")).to_have_text(TREE_VS_ASKED)
    figure = page.locator("#run-clip")
    figure.scroll_into_view_if_needed()
    expect(figure).to_have_attribute("data-state", "playing", timeout=RENDER_S * 1000)
    page.locator("#run-clip .run-clip-toggle").click()
    expect(figure).to_have_attribute("data-state", "paused")
    _audited(page, "compare page with its clip paused and the evaluation")
    page.screenshot(path=screens / "compare-clip.png", full_page=True)
