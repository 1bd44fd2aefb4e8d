"""Agent evaluation in a real browser (issue 41 §1, §3), on a desktop and on a phone: the
researcher creates an evaluation from the experiment page and invites an evaluator on its
page; the evaluator labels every pair with the clips playing (by click, arrow key and
"Can't tell"), pauses a clip (its picture is the still then), and is thanked; a second
evaluator with reduced motion sees stills with a Play control, and without JavaScript sees
stills, no toggle, and answers by the plain form. Blind: neither any page's DOM
nor any request URL holds one of the evaluation's run ids (as a path segment or a query
value), nor the words "advised" or "baseline". axe-core audits every state.

The server's run worker is off: the runs never train, each advised and baseline run gets a
real (untrained) checkpoint written into the server's data dir, as its executor would.
"""

from __future__ import annotations

import re
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlsplit

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import (
    ADMIN_TOKEN,
    DESKTOP,
    PHONE,
    fits_width,
    new_page,
    wait_until_still,
)
from tests.support.evaluations import EXPERIMENT, save_served_checkpoints
from tests.support.labelling import wait_until_prepared
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env
from tests.support.studies import Player
from tests.support.wait import wait_for

pytestmark = pytest.mark.browser
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
PAIRS = 4
#: Clips render after the stills: minutes on a loaded 2-core machine.
RENDER_MS = 400_000
URL_ATTRS = re.compile(r'(?:src|href|action|data-still|data-clip)="([^"]*)"')
#: The pair shown is ready: the script has run, and both pictures show what they should.
PAIR_READY = """([prev, kind]) => { const f = document.getElementById('pair');
  if (!f || f.dataset.ready !== 'true' || f.dataset.key === prev) return false;
  return ['left', 'right'].every(s => { const i = document.getElementById('img-' + s);
    return i.complete && i.naturalWidth > 0 && i.getAttribute('src') === i.dataset[kind]; }); }"""


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """``acv serve`` without its run worker; yields ``(base URL, data dir)``."""
    data_dir = tmp_path_factory.mktemp("acv-evaluation-data")
    env = clean_env(ACV_DATA_DIR=str(data_dir), ACV_ADMIN_TOKEN=ADMIN_TOKEN, ACV_RUN_WORKER="false")
    with acv_serve(env, data_dir / "server.log") as base:
        yield base, data_dir


@pytest.fixture(scope="module")
def api(server: tuple[str, Path]) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=server[0], headers=ADMIN, timeout=HTTP_TIMEOUT_S) as client:
        yield client


@pytest.fixture(scope="module")
def experiment(server: tuple[str, Path], api: httpx.Client) -> dict[str, Any]:
    """An experiment whose 2 advised and 2 baseline runs each saved a checkpoint."""
    body = {"name": "Eval study", "env_id": "Hopper-v5", "n_candidates": 5, "seed": 4}
    study = api.post("/api/studies", json=body | {"instructions": "Stand as tall as you can."})
    wait_until_prepared(api, study.json()["id"])
    made = api.post(
        "/api/experiments",
        json={"study_id": study.json()["id"], "teacher": "good", "seeds": 2, **EXPERIMENT},
    )
    assert made.status_code == 202, made.text
    data_dir = server[1]
    save_served_checkpoints(data_dir, made.json())
    return made.json()


def settled(page: Page, what: str) -> None:
    """axe-core on ``page`` once nothing on it animates; it fits the window's width."""
    wait_until_still(page)
    assert fits_width(page), f"{what}: wider than the window"
    assert_accessible(page, what)


class Blindness:
    """What an evaluator's browser saw: every request URL and every page's DOM."""

    def __init__(self, page: Page) -> None:
        self.urls: list[str] = []
        page.on("request", lambda request: self.urls.append(request.url))

    def check(self, page: Page, run_ids: set[str], *, practice: bool = False) -> None:
        """No run id in a URL's path segments or query values; no arm's name anywhere.
        ``practice``: practice URLs are left out of the first rule (their numbers are
        practice positions, 0 to 4, which may equal a run id by chance)."""
        html = page.content()
        for url in self.urls + URL_ATTRS.findall(html):
            parts = urlsplit(url)
            if practice and "/practice" in parts.path:
                continue
            values = set(parts.path.split("/")) | {v for _, v in parse_qsl(parts.query)}
            assert not values & run_ids, url
        for text in (html.lower(), " ".join(self.urls).lower()):
            assert "advised" not in text and "baseline" not in text


def create_and_invite(
    page: Page, base: str, experiment_id: int, where: str, errors: list[str]
) -> str:
    """Create an evaluation with the experiment page's form (a refused design first), wait
    for its clips, invite two evaluators; the evaluation page's URL."""
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/experiments/{experiment_id}")
    expect(page.locator("#evaluation-pairs")).to_have_value("20")
    settled(page, f"experiment page with its evaluations section {where}")
    # A refused design (a gate without gold pairs): the form comes back as typed.
    page.fill("#evaluation-gold-gate", "0.8")
    page.click("#create-evaluation")
    expect(page.locator("#evaluation-error")).to_contain_text("gold_pairs")
    expect(page.locator("#evaluation-gold-gate")).to_have_value("0.8")
    settled(page, f"experiment page with a refused evaluation design {where}")
    errors[:] = [e for e in errors if "422" not in e]  # the browser logs the refusal's 422
    page.fill("#evaluation-gold-gate", "")
    page.select_option("#evaluation-stimulus", "clip")
    page.fill("#evaluation-pairs", str(PAIRS))
    page.click("#create-evaluation")
    page.wait_for_url(re.compile(rf"{base}/evaluations/\d+$"))
    url = page.url
    # the page reloads itself as the stills, then the clips, are ready
    expect(page.locator("#clips")).to_have_attribute("data-clips", "ready", timeout=RENDER_MS)
    expect(page.locator("#evaluation-status")).to_have_text("ready")
    settled(page, f"evaluation page, ready {where}")
    page.fill("#count", "2")
    page.click("#invite")
    page.wait_for_url(f"{url}?invited=2#evaluators")
    expect(page.locator("#evaluator-table tbody tr")).to_have_count(2)
    return url


def wait_pair(page: Page, previous: str | None, kind: str = "clip") -> str:
    """Wait until a pair (other than ``previous``) shows ``kind`` on both sides; its key."""
    page.wait_for_function(PAIR_READY, arg=[previous or "", kind])
    key = page.get_attribute("#pair", "data-key")
    assert key
    return key


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_an_evaluation_from_the_experiment_page_to_its_answer(
    server, api: httpx.Client, experiment, browser: Browser, screens: Path, viewport
) -> None:
    base, _ = server
    where = "on a phone" if viewport == PHONE else "on a desktop"
    width = viewport["width"]
    errors: list[str] = []
    _, researcher = new_page(browser, errors, viewport=viewport)
    evaluation_url = create_and_invite(researcher, base, experiment["id"], where, errors)
    evaluation_id = int(evaluation_url.rsplit("/", 1)[1])
    links = researcher.locator("#evaluator-table td.invite input")
    first, second = links.nth(0).input_value(), links.nth(1).input_value()
    assert first.startswith(f"{base}/v/") and second.startswith(f"{base}/v/")
    slots = api.get(f"/api/evaluations/{evaluation_id}/result").json()["slots"]
    run_ids = {str(s["run_id"]) for s in slots}
    name = api.get(f"/api/evaluations/{evaluation_id}").json()["name"]

    # The evaluator: instructions, then every pair with the clips playing.
    _, page = new_page(browser, errors, viewport=viewport)
    seen = Blindness(page)
    page.goto(first)
    page.wait_for_url(f"{base}/evaluate")
    expect(page.locator("#about")).to_have_text("Stand as tall as you can.")
    expect(page.locator("#question")).to_have_text("Which agent follows the instruction better?")
    settled(page, f"evaluator instructions {where}")
    seen.check(page, run_ids)
    page.check("#share")  # agreeing to share: the page comes back saying so
    page.click("#share-save")
    expect(page.locator("#share-state")).to_contain_text("You agreed")
    expect(page.locator("#share")).to_be_checked()
    settled(page, f"evaluator instructions after agreeing to share {where}")
    page.click("#start")
    key = wait_pair(page, None)
    expect(page.locator("#motion-left")).to_have_text("Pause the left agent")
    expect(page.locator("#motion-right")).to_be_visible()
    settled(page, f"a pair with clips playing {where}")
    page.screenshot(path=screens / f"evaluate-clips-{width}.png", full_page=True)
    seen.check(page, run_ids)
    assert name not in page.content()

    # Pausing swaps the clip for its still; playing swaps it back.
    page.click("#motion-left")
    still = page.get_attribute("#img-left", "data-still")
    expect(page.locator("#img-left")).to_have_attribute("src", still or "")
    expect(page.locator("#motion-left")).to_have_text("Play the left agent")
    expect(page.locator("#img-right")).to_have_attribute("src", re.compile(r"/clip$"))
    settled(page, f"a pair with the left clip paused {where}")
    page.screenshot(path=screens / f"evaluate-paused-{width}.png", full_page=True)
    page.click("#motion-left")
    expect(page.locator("#img-left")).to_have_attribute("src", re.compile(r"/clip$"))

    # Labelling: a click, the arrow keys as on the bracket page, and "Can't tell" (T).
    page.click("#pick-left")
    key = wait_pair(page, key)
    page.keyboard.press("ArrowRight")
    key = wait_pair(page, key)
    expect(page.locator("#done-count")).to_have_text(f"2 of {PAIRS} answered")
    settled(page, f"a pair after several decisions {where}")
    seen.check(page, run_ids)
    page.keyboard.press("t")
    wait_pair(page, key)
    page.click("#tie")
    page.wait_for_url(f"{base}/evaluate/thanks")
    expect(page.locator("h1")).to_have_text("Thank you!")
    settled(page, f"evaluator thank-you page {where}")
    seen.check(page, run_ids)

    # Reduced motion: stills, each with a Play control that starts its clip.
    context, calm = new_page(browser, errors, viewport=viewport, reduced_motion="reduce")
    calm_seen = Blindness(calm)
    calm.goto(second)
    calm.click("#start")
    wait_pair(calm, None, kind="still")
    expect(calm.locator("#motion-right")).to_have_text("Play the right agent")
    settled(calm, f"a pair with reduced motion {where}")
    calm.screenshot(path=screens / f"evaluate-reduced-{width}.png", full_page=True)
    calm.click("#motion-right")
    expect(calm.locator("#img-right")).to_have_attribute("src", re.compile(r"/clip$"))
    expect(calm.locator("#motion-right")).to_have_text("Pause the right agent")
    calm_seen.check(calm, run_ids)
    context.close()

    # Without JavaScript: stills and no toggle (a clip could not be paused); the form works.
    context, plain = new_page(browser, errors, viewport=viewport, java_script_enabled=False)
    plain.goto(second)
    plain.click("#start")
    expect(plain.locator("#motion-left")).to_be_hidden()
    still = plain.get_attribute("#img-left", "data-still")
    expect(plain.locator("#img-left")).to_have_attribute("src", still or "")
    plain.click("#pick-left")
    expect(plain.locator("#done-count")).to_have_text(f"1 of {PAIRS} answered")
    context.close()

    # The researcher reads the answer: 5 answers of two evaluators, the tree sentence.
    found = api.get(f"/api/evaluations/{evaluation_id}/result").json()
    researcher.goto(evaluation_url)
    expect(researcher.locator("#counts")).to_have_text(f"{PAIRS + 1} · 2")
    assert not found["final"]  # 1 of the design's 100 evaluators finished
    expect(researcher.locator("#outcome")).to_have_attribute("data-outcome", "interim")
    expect(researcher.locator("#outcome")).to_have_text(found["sentence"])
    expect(researcher.locator("#finished")).to_have_text(f"1 of {found['planned_evaluators']}")
    expect(researcher.locator("#tree-vs-asked")).to_contain_text("does what you asked")
    expect(researcher.locator("#answers-csv")).to_be_visible()
    settled(researcher, f"evaluation page with answers {where}")
    researcher.screenshot(path=screens / f"evaluation-{width}.png", full_page=True)
    rows = api.get(f"/api/evaluations/{evaluation_id}/answers.csv").text.splitlines()[1:]
    assert len(rows) == PAIRS + 1, rows
    assert sorted(row.count(",clip,") for row in rows) == [0] + [1] * PAIRS  # no-JS: a still
    assert errors == []


def test_the_advisors_bracket_reminder(
    server, api: httpx.Client, experiment, browser: Browser, screens: Path
) -> None:
    """An advisor evaluation with the reminder on: each pair shows, folded away, the top of
    the advisor's own bracket with a sentence saying so; it opens and closes; it stays blind;
    the answer records it. (The experiment's runs trained on a simulated teacher, so the
    advisor is set in the database, as an experiment on a participant's tree would set it.)"""
    base, data_dir = server
    made = api.post(
        f"/api/experiments/{experiment['id']}/evaluations",
        json={"stimulus": "still", "pairs_per_evaluator": 2},
    )
    assert made.status_code == 201, made.text
    evaluation_id = made.json()["id"]
    wait_for(
        lambda: api.get(f"/api/evaluations/{evaluation_id}").json(),
        lambda found: found["status"] != "preparing",
        what="the evaluation's stills",
        timeout_s=600,
    )
    joined = api.post(f"/api/studies/{experiment['study_id']}/participants").json()
    advisor = Player(api, joined["id"], joined["token"], joined["invite_url"])  # type: ignore[arg-type]
    assert advisor.play() == 4
    with sqlite3.connect(data_dir / "acv.sqlite3") as db:
        db.execute(
            "UPDATE evaluations SET evaluator_kind = 'advisor', advisor_id = ?, "
            "show_bracket = 1 WHERE id = ?",
            (advisor.id, evaluation_id),
        )
    (person,) = api.post(f"/api/evaluations/{evaluation_id}/evaluators", json={"count": 1}).json()
    slots = api.get(f"/api/evaluations/{evaluation_id}/result").json()["slots"]
    run_ids = {str(s["run_id"]) for s in slots}

    errors: list[str] = []
    _, page = new_page(browser, errors, viewport=DESKTOP)
    seen = Blindness(page)
    page.goto(person["invite_url"])
    page.click("#start")
    key = wait_pair(page, None, kind="still")
    reminder = page.locator("#bracket-reminder")
    expect(reminder).to_be_visible()
    expect(reminder).not_to_have_attribute("open", "")
    page.click("#bracket-reminder summary")
    expect(page.locator("#reminder-text")).to_contain_text("your own earlier choices")
    pictures = page.locator("#bracket-reminder img")
    expect(pictures).to_have_count(4)
    expect(pictures.first).to_have_attribute("alt", "your choice in the final")
    page.wait_for_function(
        "() => [...document.querySelectorAll('#bracket-reminder img')]"
        ".every(i => i.complete && i.naturalWidth > 0)"
    )
    settled(page, "a pair with the advisor's bracket reminder open")
    page.screenshot(path=screens / "evaluate-reminder.png", full_page=True)
    seen.check(page, run_ids)
    page.set_viewport_size(PHONE)
    settled(page, "a pair with the advisor's bracket reminder open on a phone")
    page.click("#bracket-reminder summary")
    expect(page.locator("#reminder-text")).to_be_hidden()
    page.click("#pick-left")
    wait_pair(page, key, kind="still")
    expect(page.locator("#bracket-reminder")).to_be_visible()  # on every pair
    settled(page, "the next pair, its reminder folded, on a phone")
    rows = api.get(f"/api/evaluations/{evaluation_id}/answers.jsonl").text.splitlines()
    assert len(rows) == 1 and '"reminder": true' in rows[0]
    seen.check(page, run_ids)
    assert errors == []


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_practice_then_a_gold_pair(
    server, api: httpx.Client, experiment, browser: Browser, screens: Path, viewport
) -> None:
    """An evaluation with practice and gold pairs: the practice pairs come first, with their
    feedback; then the pairs, a gold one ("choose the picture with the marker") among them,
    looking like any other. Every state is audited and blind."""
    where = "on a phone" if viewport == PHONE else "on a desktop"
    body = {"stimulus": "still", "pairs_per_evaluator": 2, "gold_pairs": 2, "practice_pairs": 2}
    made = api.post(f"/api/experiments/{experiment['id']}/evaluations", json=body)
    assert made.status_code == 201, made.text
    evaluation_id = made.json()["id"]
    wait_for(
        lambda: api.get(f"/api/evaluations/{evaluation_id}").json(),
        lambda found: found["status"] != "preparing",
        what="the evaluation's stills",
        timeout_s=600,
    )
    (person,) = api.post(f"/api/evaluations/{evaluation_id}/evaluators", json={"count": 1}).json()
    slots = api.get(f"/api/evaluations/{evaluation_id}/result").json()["slots"]
    run_ids = {str(s["run_id"]) for s in slots}

    errors: list[str] = []
    _, page = new_page(browser, errors, viewport=viewport)
    seen = Blindness(page)
    page.goto(person["invite_url"])
    expect(page.locator("#practice-note")).to_be_visible()
    expect(page.locator("#start")).to_have_text("Start practice")
    page.click("#start")
    for position in range(2):
        expect(page.locator("#practice-count")).to_have_text(f"Practice pair {position + 1} of 2.")
        page.wait_for_function(
            "() => [...document.querySelectorAll('.pick img')]"
            ".every(i => i.complete && i.naturalWidth > 0)"
        )
        settled(page, f"an evaluation's practice pair {where}")
        page.click("#practice-left")
        expect(page.locator("#feedback")).to_be_visible()
        settled(page, f"an evaluation's practice feedback {where}")
        seen.check(page, run_ids, practice=True)
        page.click("#next")
    key = wait_pair(page, None, kind="still")  # the first pair is a real one
    expect(page.locator("#question")).not_to_contain_text("marker")
    page.click("#pick-left")
    wait_pair(page, key, kind="still")
    expect(page.locator("#question")).to_have_text("Check: choose the picture with the marker.")
    settled(page, f"a gold pair {where}")
    page.screenshot(path=screens / f"evaluate-gold-{viewport['width']}.png", full_page=True)
    seen.check(page, run_ids, practice=True)
    assert errors == []
