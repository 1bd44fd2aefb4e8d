"""A real browser (Playwright driving Debian's Chromium) on a finished run's pages.

``acv serve`` runs in a subprocess on 127.0.0.1 with a fresh SQLite data dir and its own
worker. Through the REST API a participant labels an 8-candidate Humanoid bracket the way
the ``standing`` teacher would; a short ``bipars-em`` run and a tiny ``ppo`` baseline train
on that advice. The researcher's browser then opens the run page and the comparison page:
both Preference Trees are drawn with thumbnails, the rejected advice is listed as image
pairs (as many as the metrics say were overturned, and at least one on a view that overturns
some), the verdict names the kept choices, the checkpoint slider redraws the agent's tree,
the two runs on the same advice are compared side by side, and no script or CSP error
occurs. Screenshots go to ``/tmp/acv_screens`` (``compare.png``, ``compare-value.png``,
``run.png``, ``compare-runs.png``).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from playwright.sync_api import Browser, Page, expect, sync_playwright

from app.db import make_engine, make_sessions
from app.models import Experiment, ExperimentRun
from engine.envs import env_model
from engine.judges import JUDGES
from engine.teachers import standing_score
from tests.support.a11y import assert_accessible
from tests.support.browser import (  # noqa: F401 (SETTLE_TIMEOUT_MS sets expect's timeout)
    PHONE,
    SETTLE_TIMEOUT_MS,
    new_page,
    wait_until_still,
)
from tests.support.labelling import label_bracket, wait_until_prepared
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env
from tests.support.wait import wait_for

pytestmark = [pytest.mark.browser, pytest.mark.training]

ADMIN_TOKEN = "compare-browser-admin-token-0123456789"
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]
SCREENS = Path(os.environ.get("ACV_SCREENS", "/tmp/acv_screens"))
N_CANDIDATES = 8
RUN = {
    "algo": "bipars-em",
    "timesteps": 4096,
    "seed": 1,
    "n_envs": 1,
    "num_steps": 256,
    "num_minibatches": 4,
    "update_epochs": 2,
    "checkpoint_every": 1024,
}
#: The baseline on the same advice: two checkpoints, a few seconds.
BASELINE = RUN | {"algo": "ppo", "timesteps": 512, "checkpoint_every": 256}


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The served app's data dir (its SQLite database is ``acv.sqlite3`` there)."""
    return tmp_path_factory.mktemp("acv-compare-data")


@pytest.fixture(scope="module")
def server(data_dir: Path) -> Iterator[str]:
    """``acv serve`` (with its run worker) on a free port; yields the base URL."""
    env = clean_env(ACV_DATA_DIR=str(data_dir), ACV_ADMIN_TOKEN=ADMIN_TOKEN)
    with acv_serve(env, data_dir.parent / "server.log", "--no-access-log") as base:
        yield base


def _standing_participant(api: httpx.Client, study_id: int) -> int:
    """Invite a participant and label every match as the ``standing`` teacher would."""
    cands = api.get(f"/api/studies/{study_id}/candidates").json()
    scores = standing_score(np.array([c["qpos"] for c in cands]), env_model("Humanoid-v5"))
    token = api.post(f"/api/studies/{study_id}/participants").json()["token"]

    def standing(match: dict) -> int:
        a, b = match["a"]["candidate_id"], match["b"]["candidate_id"]
        return a if scores[a] >= scores[b] else b

    label_bracket(api, token, standing)
    me = {"Authorization": f"Bearer {token}"}
    return api.get("/api/participants/me", headers=me).json()["id"]


@pytest.fixture(scope="module")
def finished_run(server: str) -> dict:
    """A succeeded ``bipars-em`` run on a standing-advice participant's tree, and (id under
    ``baseline``) a succeeded ``ppo`` run on the same advice."""
    with httpx.Client(base_url=server, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        study = api.post(
            "/api/studies",
            json={
                "name": "Standing advice",
                "env_id": "Humanoid-v5",
                "n_candidates": N_CANDIDATES,
                "seed": 5,
            },
        ).json()
        wait_until_prepared(api, study["id"])
        pid = _standing_participant(api, study["id"])
        ids = []
        for body in (RUN, BASELINE):
            created = api.post(
                "/api/runs", json={"study_id": study["id"], "participant_id": pid, **body}
            )
            assert created.status_code == 202, created.text
            ids.append(created.json()["id"])
        run, baseline = (
            wait_for(
                lambda i=i: api.get(f"/api/runs/{i}").json(),
                lambda r: r["status"] not in ("queued", "running"),
                what=f"run {i}",
                timeout_s=180,
                every_s=0.3,
            )
            for i in ids
        )
        assert run["status"] == baseline["status"] == "succeeded", (run, baseline)
        run["conformance"] = api.get(f"/api/runs/{run['id']}/conformance").json()
        run["baseline"] = baseline["id"]
        return run


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    """One Chromium for the module (Playwright's sync API runs one at a time)."""
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield browser
        browser.close()


@pytest.fixture(scope="module")
def page(server: str, browser: Browser) -> Iterator[tuple[Page, list[str]]]:
    """A logged-in researcher's page; collects console errors and uncaught script errors."""
    context = browser.new_context(viewport={"width": 1400, "height": 1000})
    context.set_default_timeout(60_000)
    errors: list[str] = []
    p = context.new_page()
    p.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    p.on("pageerror", lambda exc: errors.append(str(exc)))
    p.goto(f"{server}/login#token={ADMIN_TOKEN}")
    p.wait_for_url(f"{server}/studies")
    yield p, errors
    context.close()


def test_comparison_page_shows_both_trees_and_the_rejected_advice(
    server: str, finished_run: dict, page: tuple[Page, list[str]]
) -> None:
    p, errors = page
    run_id, metrics = finished_run["id"], finished_run["conformance"]
    p.goto(f"{server}/runs/{run_id}/compare")
    expect(p.locator("#human-tree svg.pref-tree .node")).to_have_count(N_CANDIDATES)
    expect(p.locator("#agent-tree svg.pref-tree .node")).to_have_count(N_CANDIDATES)
    expect(p.locator("#human-tree svg image")).to_have_count(N_CANDIDATES)
    contested = metrics["contested"]
    lead = (
        rf"Of the {contested['n']} choices where your advice goes against the environment's "
        rf"reward, the agent kept {contested['kept']}\."
        if contested["n"]
        else r"None of your choices goes against the environment's reward, so this bracket "
        r"cannot tell whether the agent used your advice\."
    )
    expect(p.locator("#verdict")).to_have_text(
        re.compile(
            rf"^{lead} Overall it kept {metrics['n_agree']} of {N_CANDIDATES - 1} of your choices"
        )
    )
    expect(p.locator("#judges-body tr")).to_have_count(len(JUDGES))  # every judge, side by side
    for judge in JUDGES:
        expect(p.locator(f"#judges-body tr[data-judge='{judge}']")).to_have_count(1)
    # the page judges by return by default, as the fixture's conformance does
    expect(p.locator("#judges-body tr[data-judge='return'] td").nth(1)).to_have_text(
        f"{metrics['n_agree']} / {N_CANDIDATES - 1}"
    )
    expect(p.locator("#candidates tbody tr")).to_have_count(N_CANDIDATES)
    expect(p.locator("#candidates tbody tr").first.locator("a")).to_have_attribute(
        "href", re.compile(r"/candidates/0/image$")
    )
    p.locator("#candidates th[data-sort='behaviour'] button").click()  # sort by a column
    expect(p.locator("#candidates th[data-sort='behaviour']")).to_have_attribute(
        "aria-sort", "ascending"
    )
    cells = p.locator("#candidates tbody tr td:nth-child(8)")
    shown = [float(t) for t in cells.all_text_contents()]
    assert shown == sorted(shown)
    assert_accessible(p, "compare page")
    champion = p.locator("#human-tree svg.pref-tree .node.champion")
    champion.focus()  # a tree's node is a button for the keyboard too
    p.keyboard.press("Enter")
    expect(p.locator("#preview")).to_be_visible()
    expect(p.locator("#preview-caption")).to_have_text(re.compile(r"^#\d+ \(human tree\)$"))
    p.keyboard.press("Escape")
    expect(p.locator("#preview")).to_be_hidden()
    n_rejected = len(metrics["rejected"])
    expect(p.locator("#rejected .pair")).to_have_count(n_rejected)
    expect(p.locator("#rejected .pair img")).to_have_count(2 * n_rejected)
    if n_rejected == 0:
        expect(p.locator("#rejected")).to_have_text(
            "None: the agent kept every choice at this checkpoint."
        )
    expect(p.locator("#human-tree .node.rejected")).to_have_count(
        len({r["b"] if r["human_winner"] == r["a"] else r["a"] for r in metrics["rejected"]})
    )
    # The curve is computed over every checkpoint: slow on a loaded machine, so wait for it.
    expect(p.locator("#compare")).to_have_attribute("data-curve-judge", "return", timeout=120_000)
    expect(p.locator("#chart-curve svg circle.dot")).to_have_count(2 * 4)  # 4 checkpoints
    assert_accessible(p, "comparison page")
    SCREENS.mkdir(parents=True, exist_ok=True)
    p.screenshot(path=SCREENS / "compare.png", full_page=True)

    p.locator("#checkpoint").fill("0")  # the slider: the first checkpoint
    p.locator("#checkpoint").dispatch_event("change")
    expect(p.locator("#compare")).to_have_attribute("data-loaded", "1024:return")
    expect(p.locator("#agent-title")).to_have_text("(step 1024)")
    expect(p.locator("#exports a[data-export='report.html']")).to_have_attribute(
        "href", f"/api/runs/{run_id}/report.html?judge=return&checkpoint=1024"
    )

    p.select_option("#judge", "shaped-value")  # the shaped critic: other picks, same page
    expect(p.locator("#compare")).to_have_attribute("data-loaded", "1024:shaped-value")
    rejected = httpx.get(
        f"{server}/api/runs/{run_id}/conformance?checkpoint=1024&judge=shaped-value",
        headers=ADMIN,
        timeout=HTTP_TIMEOUT_S,
    ).json()["rejected"]
    # This view overturns some advice (3 of 7 with this seed): the list must show it.
    assert len(rejected) >= 1, "no overturned match to list: change the seed or the view"
    pairs = p.locator("#rejected .pair")
    expect(pairs).to_have_count(len(rejected))
    for pair, r in zip(pairs.all(), rejected, strict=True):
        expect(pair.locator("img")).to_have_count(2)
        expect(pair.locator("img").first).to_have_attribute(
            "src", re.compile(rf"/candidates/{r['human_winner']}/image\?size=thumb$")
        )
        expect(pair).to_contain_text(f"Round {r['round']}: you preferred #{r['human_winner']}")
    expect(p.locator("#compare")).to_have_attribute("data-curve-judge", "shaped-value")
    p.screenshot(path=SCREENS / "compare-value.png", full_page=True)
    assert errors == []


def test_run_page_shows_progress_curves_and_checkpoints(
    server: str, finished_run: dict, page: tuple[Page, list[str]]
) -> None:
    p, errors = page
    p.goto(f"{server}/runs/{finished_run['id']}")
    expect(p.locator("#run-status")).to_have_text("succeeded")
    expect(p.locator("#run-checkpoints li[data-step]")).to_have_count(4)
    expect(p.locator("#chart-z svg g.line path")).to_have_count(1)  # Observable Plot's line
    expect(p.locator("#chart-z svg g.band path")).to_have_count(1)  # mean ± std
    expect(p.locator("svg style")).to_have_count(0)  # Plot's inline <style>: the CSP forbids it
    assert_accessible(p, "run page")
    expect(p.locator("#run-progress")).to_have_attribute("value", "4096")
    p.screenshot(path=SCREENS / "run.png", full_page=True)
    p.goto(f"{server}/runs/{finished_run['id']}/compare")
    expect(p.locator(f"a[href='/runs/{finished_run['id']}/compare-runs']")).to_have_text(
        "compare the 2 runs on this advice"
    )
    p.goto(f"{server}/runs/{finished_run['id']}/compare-runs")
    rows = p.locator("table.runs-side-by-side tbody tr")
    expect(rows).to_have_count(2)  # bipars-em and the ppo baseline, oldest first
    for row, (run_id, algo) in zip(
        rows.all(),
        [(finished_run["id"], "bipars-em"), (finished_run["baseline"], "ppo")],
        strict=True,
    ):
        expect(row).to_have_attribute("data-run-id", str(run_id))
        expect(row.locator("td").nth(1)).to_have_text(algo)
    expect(p.locator("#chart-runs svg g.line path")).to_have_count(2)  # one curve per run
    expect(p.locator("#chart-runs .plot-legend li")).to_have_count(2)
    assert_accessible(p, "runs on the same advice")
    p.screenshot(path=SCREENS / "compare-runs.png", full_page=True)
    assert errors == []


#: Draws 7 series with acvPlots (the page's own scripts) into a new chart box, and reads each
#: line's and each legend key's stroke colour and dash pattern, and the x a series' dot opens.
SEVEN_SERIES = """() => {
  const box = document.body.appendChild(document.createElement("div"));
  box.className = "chart";
  const series = Array.from({ length: 7 }, (_, i) => ({ label: `run ${i}`,
    points: [[i, i], [10 + i, i + 1]] }));
  let picked = null;
  acvPlots.lines(box, series, { onPick: (x) => { picked = x; } });
  const look = (el) => `${getComputedStyle(el).stroke}|${getComputedStyle(el).strokeDasharray}`;
  const lines = [...box.querySelectorAll("svg.acv-plot g.line path")].map(look);
  const keys = [...box.querySelectorAll(".plot-legend line")].map(look);
  box.querySelectorAll("g.dot.series-5 circle")[1].dispatchEvent(new MouseEvent("click"));
  return { lines, keys, picked };
}"""


def test_chart_series_differ_without_colour_and_never_repeat(
    server: str, finished_run: dict, page: tuple[Page, list[str]]
) -> None:
    """Each series has its own colour and dash pattern, shown in its legend key too (WCAG
    1.4.1: not by colour alone); a sixth and seventh series repeat neither, and a dot of the
    sixth opens its own point, not the first series' (they share a colour)."""
    p, errors = page
    p.goto(f"{server}/runs/{finished_run['id']}/compare-runs")
    expect(p.locator("#chart-runs svg.acv-plot")).to_have_count(1)
    drawn = p.evaluate(SEVEN_SERIES)
    assert len(set(drawn["lines"])) == 7, drawn
    assert drawn["keys"] == drawn["lines"]
    assert len({look.split("|")[1] for look in drawn["lines"][:4]}) == 4  # 4 patterns
    assert drawn["picked"] == 15  # series 5's second point
    p.locator(".chart").last.screenshot(path=SCREENS / "chart-seven-series.png")
    assert errors == []


def test_new_run_without_a_study_picks_one(
    server: str, finished_run: dict, page: tuple[Page, list[str]]
) -> None:
    """``/runs/new`` (bookmarked or typed) is the study picker; picking opens the form."""
    p, errors = page
    p.goto(f"{server}/runs/new")
    assert_accessible(p, "study picker")
    p.select_option("#study_id", str(finished_run["study_id"]))
    p.click("text=New run…")
    p.wait_for_url(re.compile(rf"/runs/new\?study_id={finished_run['study_id']}$"))
    expect(p.locator("form[action='/runs'] #timesteps")).to_be_visible()
    assert errors == []


def test_the_html_report_is_accessible(
    server: str, finished_run: dict, page: tuple[Page, list[str]]
) -> None:
    """The report the compare page exports, opened as a researcher would open the link."""
    p, errors = page
    p.goto(f"{server}/api/runs/{finished_run['id']}/report.html?judge=return&checkpoint=1024")
    expect(p.locator("h1")).to_contain_text(f"run {finished_run['id']}")
    wait_until_still(p)
    assert_accessible(p, "HTML report")
    assert errors == []


def test_researcher_pages_with_tables_on_a_phone(
    server: str, finished_run: dict, browser: Browser
) -> None:
    """Every researcher page with a table, on a phone, once settled: no serious or critical
    axe violation. A table wider than the screen scrolls inside a region that the keyboard
    can reach and that says what it holds."""
    run, study = finished_run["id"], finished_run["study_id"]
    paths = ["/studies", f"/studies/{study}", "/runs", f"/runs/{run}", f"/runs/{run}/compare"]
    paths += [f"/runs/{run}/compare-runs", "/surveys"]
    errors: list[str] = []
    context, p = new_page(browser, errors, viewport=PHONE, is_mobile=True, has_touch=True)
    p.goto(f"{server}/login#token={ADMIN_TOKEN}")
    p.wait_for_url(f"{server}/studies")
    for path in paths:
        p.goto(f"{server}{path}")
        p.wait_for_load_state("networkidle")
        wait_until_still(p)
        assert_accessible(p, f"{path} on a phone")
    context.close()
    assert errors == []


def test_the_html_report_of_a_run_in_an_experiment_is_accessible(
    server: str, data_dir: Path, finished_run: dict, page: tuple[Page, list[str]]
) -> None:
    """With its experiment's verdict and what the validation found of the judges. Last in the
    module: the run joins an experiment (as advised, its ppo run as baseline) for good."""
    engine = make_engine(f"sqlite:///{data_dir / 'acv.sqlite3'}")
    try:
        with make_sessions(engine)() as session, session.begin():
            experiment = Experiment(
                study_id=finished_run["study_id"], spec={}, seeds=[0], pilot_seeds=[]
            )
            session.add(experiment)
            session.flush()
            for run_id, role in (
                (finished_run["id"], "advised"),
                (finished_run["baseline"], "baseline"),
            ):
                session.add(ExperimentRun(experiment_id=experiment.id, run_id=run_id, role=role))
    finally:
        engine.dispose()
    p, errors = page
    p.goto(f"{server}/api/runs/{finished_run['id']}/report.html?judge=return&checkpoint=1024")
    expect(p.locator("body")).to_contain_text("Did the advice change the agent?")
    expect(p.locator("body")).to_contain_text("no judge passed ACV's validation")
    wait_until_still(p)
    assert_accessible(p, "HTML report of a run in an experiment")
    assert errors == []
