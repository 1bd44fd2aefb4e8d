"""A real browser (Debian's Chromium through Playwright) through a survey: the researcher
builds a two-stimulus survey with the new-survey form and invites a respondent; the
respondent answers it on a 390x844 phone (taps, one stimulus per screen), then resumes
through the link on a desktop; the survey page then shows their answers. A second test
builds a survey with blank-template questions, an uploaded tree and a run's stored agent
tree through the form. axe-core checks every survey page (no serious or critical
violation). Screenshots go to the test's tmp dir and /tmp/acv_screens.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Page, expect

from app.db import make_engine, make_sessions
from app.models import CheckpointArtefact, Run
from app.settings import SQLITE_FILE
from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN, fits_width, new_page
from tests.support.server import HTTP_TIMEOUT_S
from tests.support.surveys import READY, two_finished_participants

pytestmark = pytest.mark.browser

PHONE = {"width": 390, "height": 844}
DESKTOP = {"width": 1280, "height": 900}
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}


def build_survey(page: Page, base: str) -> str:
    """Log in and create a two-stimulus survey with the form; returns the survey page URL."""
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.click("nav >> text=Surveys")
    assert_accessible(page, "surveys list")
    page.click("text=New survey")
    expect(page.locator("#survey-form")).to_have_attribute("data-ready", "true")
    page.fill("#name", "Phone survey")
    page.fill("#term2", "a bent posture")
    page.click("#add-stimulus")
    stimuli = page.locator("#stimulus-list > li")
    expect(stimuli).to_have_count(2)
    for i in range(2):
        pickers = stimuli.nth(i).locator("select[data-field=participant_id]")
        pickers.nth(0).select_option(index=0)
        pickers.nth(1).select_option(index=1)
    assert_accessible(page, "new survey form")
    page.click("#create")
    page.wait_for_url(re.compile(r".*/surveys/\d+$"))
    expect(page.locator(".stimulus-preview svg.pref-tree")).to_have_count(4)
    return page.url


def answer_screen(p: Page, q1: str, q2: str, confidence: str) -> str:
    """Tap the answers of the shown screen and submit; returns its position."""
    p.wait_for_function(READY)
    position = p.get_attribute("#respond", "data-position")
    p.tap(f"fieldset[data-key=q1] label:has(input[value={q1}])")
    p.tap(f"fieldset[data-key=q1] .confidence label:has(input[value='{confidence}'])")
    p.tap(f"fieldset[data-key=q2] label:has(input[value={q2}])")
    p.tap(f"fieldset[data-key=q2] .confidence label:has(input[value='{confidence}'])")
    p.tap("#submit")
    p.wait_for_function(
        "prev => { const r = document.getElementById('respond'); return "
        "r.dataset.finished === 'true' || (r.dataset.ready === 'true' && "
        "r.dataset.position !== prev); }",
        arg=position,
    )
    return position


def test_respondent_on_a_phone_and_the_results(server, browser, screens: Path) -> None:
    base, _ = server
    two_finished_participants(base)
    errors: list[str] = []
    researcher, page = new_page(browser, errors, viewport=DESKTOP)
    survey_url = build_survey(page, base)
    count = page.locator("#count").input_value()
    page.fill("#count", "0")  # refused: the API's list of errors, in words
    page.click("#add-respondents")
    expect(page.locator("#add-message")).to_contain_text(
        "Could not invite: count: Input should be greater than or equal to 1"
    )
    refused = [e for e in errors if "status of 422" in e and "/respondents" in e]
    assert len(refused) == 1  # Chromium logs the refusal's status; nothing else
    errors.remove(refused[0])
    page.fill("#count", count)
    page.click("#add-respondents")
    invite = page.locator("td.invite input").first
    page.wait_for_selector("td.invite input")
    link = invite.input_value()
    assert link.startswith(f"{base}/r/")
    assert_accessible(page, "survey page")

    phone, p = new_page(browser, errors, viewport=PHONE, is_mobile=True, has_touch=True)
    p.goto(link)
    p.wait_for_url(f"{base}/survey")
    expect(p.locator("#intro")).to_be_visible()
    assert_accessible(p, "respondent intro")
    p.tap("#start")
    p.wait_for_function(READY)
    expect(p.locator("#screen-title")).to_have_text("Screen 1 of 2")
    expect(p.locator("#screen-title")).to_be_focused()  # Start is gone: the new screen's title
    expect(p.locator("#tree-left svg.pref-tree image")).to_have_count(5)
    expect(p.locator("#tree-right svg.pref-tree g.node")).to_have_count(5)
    words = p.locator("#tree-left p.visually-hidden")  # the tree in words, for screen readers
    expect(words).to_contain_text("The champion is #")
    expect(words).to_contain_text(" beat #")
    expect(p.locator("svg.pref-tree .rejected")).to_have_count(0)  # highlights are off
    names = [p.inner_text("#left-name"), p.inner_text("#right-name")]
    assert sorted(names) == ["Tree 1", "Tree 2"]
    assert fits_width(p)
    assert_accessible(p, "stimulus screen")
    p.screenshot(path=screens / "survey-stimulus-phone.png", full_page=True)
    p.tap("#submit")  # nothing chosen yet: nothing is sent
    expect(p.locator("#answer-error")).to_contain_text("Please answer")
    stale = p.context.new_page()  # a second tab on screen 1, answered after the first
    stale.goto(link)
    stale.tap("#start")  # nothing answered yet: it starts from the intro too
    stale.wait_for_function(READY)
    assert answer_screen(p, "different", "yes", "4") == "1"
    assert answer_screen(stale, "same", "no", "2") == "1"  # 409: it moves on and says so
    expect(stale.locator("#screen-title")).to_have_text("Screen 2 of 2")
    expect(stale.locator("#answer-error")).to_contain_text("those answers are kept")
    assert_accessible(stale, "the next screen after a second tab's answer")
    stale.close()
    phone.close()

    # The link resumes at screen 2, here on a desktop: the trees side by side.
    again, p = new_page(browser, errors, viewport=DESKTOP, has_touch=True)
    p.goto(link)
    p.wait_for_function(READY)
    expect(p.locator("#screen-title")).to_have_text("Screen 2 of 2")
    left, right = (p.locator(f"#tree-{side}").bounding_box() for side in ("left", "right"))
    assert left["x"] + left["width"] <= right["x"] and abs(left["y"] - right["y"]) < 1
    assert fits_width(p)
    assert_accessible(p, "stimulus screen on a desktop")
    p.screenshot(path=screens / "survey-stimulus-desktop.png", full_page=True)
    # The network fails on Submit: the page says so and Submit works again (it stayed off).
    p.route("**/answers", lambda route: route.abort())
    p.click("fieldset[data-key=q1] label:has(input[value=same])")
    p.click("fieldset[data-key=q1] .confidence label:has(input[value='2'])")
    p.click("fieldset[data-key=q2] label:has(input[value=no])")
    p.click("fieldset[data-key=q2] .confidence label:has(input[value='2'])")
    p.click("#submit")
    expect(p.locator("#answer-error")).to_contain_text("Your answers were not sent")
    expect(p.locator("#submit")).to_be_enabled()
    p.unroute("**/answers")
    errors[:] = [e for e in errors if "ERR_FAILED" not in e]  # the aborted request's log
    assert answer_screen(p, "same", "no", "2") == "2"
    expect(p.locator("#done")).to_be_visible()
    assert_accessible(p, "thank-you screen")
    again.close()

    page.goto(survey_url)
    rows = page.locator("table.results.all tbody tr")
    expect(rows).to_have_count(4)  # 2 stimuli x 2 questions
    table = page.locator("table.results.all")
    for text in ("same: 0", "different: 1", "same: 1", "yes: 1", "no: 1", "1/1 (100%)", "0/1 (0%)"):
        expect(table).to_contain_text(text)
    expect(page.locator("table.results.paper")).to_contain_text("17/20 (85%)")
    expect(page.locator("table.results.paper")).to_contain_text("0.62–0.97")
    expect(page.locator("#respondent-counts")).to_contain_text("1 finished")
    assert_accessible(page, "results")
    page.screenshot(path=screens / "survey-results-desktop.png", full_page=True)
    researcher.close()
    assert errors == []


def stored_agent_tree(log: Path, study_id: int, tree: dict) -> int:
    """A run row of the server's study whose checkpoint 512 holds ``tree`` as its "value"
    agent tree (what the run executor stores), written into the server's SQLite file."""
    data_dir = log.parent  # the ``server`` fixture's (several may exist in this worker)
    engine = make_engine(f"sqlite:///{data_dir / SQLITE_FILE}")
    try:
        with make_sessions(engine)() as session:
            run = Run(
                study_id=study_id,
                teacher="standing",
                algo="bipars-em",
                timesteps=512,
                seed=0,
                n_envs=1,
                config={},
                status="succeeded",
                progress=512,
            )
            session.add(run)
            session.flush()
            session.add(
                CheckpointArtefact(
                    run_id=run.id,
                    step=512,
                    payload={"judges": {"value": {"tree": tree | {"judge": "agent:value"}}}},
                )
            )
            session.commit()
            return run.id
    finally:
        engine.dispose()


def test_blank_questions_an_upload_and_a_run_through_the_form(
    server,
    browser,
    tmp_path: Path,
) -> None:
    base, log = server
    study_id = two_finished_participants(base)
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        people = [
            p
            for p in api.get("/api/surveys/sources").json()["participants"]
            if p["study_id"] == study_id
        ]
        human = api.get(f"/api/participants/{people[0]['participant_id']}/tree").json()
        agent = api.get(f"/api/participants/{people[1]['participant_id']}/tree").json()
    run_id = stored_agent_tree(log, study_id, agent)
    upload = tmp_path / "human.acv-tree.json"
    upload.write_text(json.dumps(human))
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=DESKTOP)
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/surveys/new")
    expect(page.locator("#survey-form")).to_have_attribute("data-ready", "true")
    page.fill("#name", "Own questions")
    page.check("input[name=template][value=blank]")
    question = page.locator("#question-list > li").nth(0)
    question.locator("[data-field=text]").fill("Do the trees agree?")
    question.locator("[data-field=options]").fill("agree\ndisagree")
    question.locator("[data-field=expected]").fill("disagree")
    question.locator("[data-field=confidence]").check()
    page.click("#add-question")
    likert = page.locator("#question-list > li").nth(1)
    likert.locator("[data-field=kind]").select_option("likert")
    expect(likert.locator("[data-field=expected]")).to_be_hidden()
    likert.locator("[data-field=points]").select_option("7")
    likert.locator("[data-field=text]").fill("The trees are easy to read.")
    one, two = page.locator(".tree-source").nth(0), page.locator(".tree-source").nth(1)
    one.locator("[data-field=kind]").select_option("upload")
    one.locator("[data-field=file]").set_input_files(upload)
    one.locator("[data-field=study_id]").select_option(str(study_id))
    two.locator("[data-field=kind]").select_option("run")
    two.locator("[data-field=checkpoint]").select_option(f"{run_id}:512")
    expect(two.locator("[data-field=judge] option")).to_have_text(["shaped-value"])
    page.check("#highlights")
    page.check("input[name=assignment][value=round_robin]")
    page.fill("#seed", "42")
    page.click("#create")
    page.wait_for_url(re.compile(r".*/surveys/\d+$"))
    survey_id = page.url.rsplit("/", 1)[1]
    expect(page.locator(".stimulus-preview svg.pref-tree image")).to_have_count(10)
    expect(page.locator(".stimulus-preview svg.pref-tree .rejected").first).to_be_visible()
    context.close()
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        survey = api.get(f"/api/surveys/{survey_id}").json()
    assert [(q["kind"], q["expected"], q["confidence"]) for q in survey["questions"]] == [
        ("choice", "disagree", True),
        ("likert", None, False),
    ]
    assert survey["questions"][1]["options"] == [str(i) for i in range(1, 8)]
    assert (survey["highlights"], survey["assignment"], survey["seed"]) == (True, "round_robin", 42)
    tree1, tree2 = survey["stimuli"][0]["trees"]
    assert tree1["source"]["kind"] == "upload" and tree1["study_id"] == study_id
    assert tree2["source"] == {
        "kind": "run",
        "run_id": run_id,
        "checkpoint": 512,
        "judge": "shaped-value",
    }
    assert errors == []
