"""An evaluator withdraws, and the researcher sets the evaluation's open link (issue 41 §1:
links like any study's), on both databases: ``/evaluate/withdraw`` asks first, withdraws only
by its own button (with CSRF), then shows the ended page with the open link's decline code;
the evaluation page's open-link form refuses bad input with a 4xx page that says why, and
saves good input, after which a visitor through ``/e/<slug>`` lands on ``/evaluate``.

The evaluation is a bare one (its rows written directly, nothing rendered): these pages need
its evaluators and their pairs, not its pictures. In a real browser, on a desktop and on a
phone, axe-core audits the withdraw page and the ended page it leads to.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from playwright.sync_api import Browser, expect

from app.db import make_engine, make_sessions
from app.settings import SQLITE_FILE
from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN as SERVER_TOKEN
from tests.support.browser import DESKTOP, PHONE, fits_width, new_page, wait_until_still
from tests.support.crowd import join
from tests.support.evaluations import bare_evaluation
from tests.support.labelling import wait_until_prepared
from tests.support.runs import TINY, create_run, run_app
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env
from tests.support.studies import new_study
from tests.support.web import ADMIN, CSRF_RE, audit, csrf_token, logged_in
from tests.support.web import browser as cookie_jar

WITHDRAW = "/evaluate/withdraw"
#: The open-link form as a researcher fills it in.
FORM = {
    "enabled": "on",
    "max_participants": "5",
    "external_params": "PROLIFIC_PID",
    "completion_code": "DONE-7",
    "decline_code": "LEFT-7",
    "redirect_url": "https://example.org/back?cc={code}",
    "consent_text": "",
    "time_limit_min": "30",
}


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def researcher(client: TestClient) -> TestClient:
    return logged_in(client)


@pytest.fixture(scope="module")
def run_id(client: TestClient) -> int:
    """A run (never trained: the worker is off) for the bare evaluations' slots."""
    study = new_study(client, n_candidates=3, seed=5)
    return create_run(
        client, study_id=study["id"], teacher="good", algo="bipars-em", timesteps=256, **TINY
    )


@pytest.fixture(scope="module")
def evaluation_id(client: TestClient, run_id: int) -> int:
    return bare_evaluation(client, run_id=run_id)


def _invited(client: TestClient, evaluation_id: int) -> TestClient:
    """A new invited evaluator's browser, its cookie set by the invite link."""
    made = client.post(
        f"/api/evaluations/{evaluation_id}/evaluators", json={"count": 1}, headers=ADMIN
    )
    assert made.status_code == 201, made.text
    token = made.json()[0]["invite_url"].rsplit("/", 1)[1]
    person = cookie_jar(client)
    assert person.get(f"/v/{token}").status_code == 303
    return person


def _form(page: TestClient, path: str) -> str:
    """The CSRF token of the page ``path`` (a 200)."""
    response = page.get(path)
    assert response.status_code == 200, response.text
    match = CSRF_RE.search(response.text)
    assert match, path
    return match.group(1)


def test_the_pair_and_instructions_pages_link_to_the_withdraw_page(client, evaluation_id) -> None:
    person = _invited(client, evaluation_id)
    for path in ("/evaluate", "/evaluate/pair"):
        html = person.get(path).text
        assert f'href="{WITHDRAW}" id="withdraw-link"' in html, path
    page = person.get(WITHDRAW)
    assert page.status_code == 200 and "Withdraw from this evaluation?" in page.text
    assert "kept apart and will not be used" in page.text and 'href="/evaluate/pair"' in page.text
    assert 'name="decision" value="withdraw"' in page.text and audit(page.text) == []
    assert "script-src 'self'" in page.headers["content-security-policy"]


def test_withdrawing_takes_the_button_and_csrf_then_ends(client, evaluation_id) -> None:
    person = _invited(client, evaluation_id)
    token = _form(person, WITHDRAW)
    assert person.post(WITHDRAW, data={"decision": "withdraw"}).status_code == 403  # no CSRF
    wrong = person.post(WITHDRAW, data={"csrf_token": token, "decision": "yes"})
    assert wrong.status_code == 422 and "Withdraw button" in wrong.text
    assert wrong.headers["content-type"].startswith("text/html")
    assert person.get("/evaluate").status_code == 200  # still in
    done = person.post(WITHDRAW, data={"csrf_token": token, "decision": "withdraw"})
    assert done.status_code == 303 and done.headers["location"] == "/evaluate/ended"
    ended = person.get("/evaluate/ended")
    assert ended.status_code == 200 and "You withdrew" in ended.text
    assert "completion-code" not in ended.text  # an invited evaluator: no open link, no code
    for path in ("/evaluate", "/evaluate/pair", WITHDRAW):
        assert person.get(path).headers["location"] == "/evaluate/ended", path
    again = person.post(WITHDRAW, data={"csrf_token": token, "decision": "withdraw"})
    assert again.status_code == 303 and again.headers["location"] == "/evaluate/ended"  # a reload
    stranger = cookie_jar(client)
    assert stranger.get(WITHDRAW).status_code == 401
    assert stranger.post(WITHDRAW, data={"decision": "withdraw"}).status_code in (401, 403)


def test_the_evaluation_page_shows_no_open_link_before_the_form(researcher, evaluation_id) -> None:
    html = researcher.get(f"/evaluations/{evaluation_id}").text
    assert 'id="crowd"' in html and 'id="no-open-link"' in html
    assert f'action="/evaluations/{evaluation_id}/crowd"' in html and 'id="time_limit_min"' in html
    assert audit(html) == []


@pytest.mark.parametrize(
    ("field", "bad", "says"),
    [
        ("max_participants", "many", "max_participants must be a whole number"),
        ("max_participants", "0", "max_participants"),
        ("redirect_url", "ftp://x.org/", "redirect_url"),
        ("time_limit_min", "soon", "time_limit_min must be a whole number"),
        ("time_limit_min", "99999", "time_limit_min"),
        ("external_params", "1bad", "external_params"),
    ],
)
def test_a_bad_open_link_form_is_a_4xx_page_that_says_why(
    client, researcher, run_id, field, bad, says
) -> None:
    evaluation_id = bare_evaluation(client, run_id=run_id)
    path = f"/evaluations/{evaluation_id}"
    data = FORM | {field: bad, "csrf_token": csrf_token(researcher, path)}
    response = researcher.post(f"{path}/crowd", data=data)
    assert response.status_code == 422, response.text
    assert says in response.text and response.headers["content-type"].startswith("text/html")
    assert 'id="crowd-error" role="alert">Not saved:' in response.text  # the page, again
    assert f'value="{bad}"' in response.text  # with the form as it was sent
    assert client.get(f"/api/evaluations/{evaluation_id}/crowd", headers=ADMIN).status_code == 404


def test_the_open_link_form_needs_a_ready_evaluation_a_researcher_and_csrf(
    client, researcher, evaluation_id
) -> None:
    preparing = bare_evaluation(client)  # no slots, still preparing
    data = FORM | {"csrf_token": csrf_token(researcher, f"/evaluations/{evaluation_id}")}
    refused = researcher.post(f"/evaluations/{preparing}/crowd", data=data)
    assert refused.status_code == 409 and refused.headers["content-type"].startswith("text/html")
    assert "open link can be set once" in researcher.get(f"/evaluations/{preparing}").text
    assert researcher.post("/evaluations/999999/crowd", data=data).status_code == 404
    assert researcher.post("/evaluations/x/crowd", data=data).status_code in (404, 422)
    no_csrf = researcher.post(f"/evaluations/{evaluation_id}/crowd", data=FORM)
    assert no_csrf.status_code == 403
    stranger = cookie_jar(client).post(f"/evaluations/{evaluation_id}/crowd", data=data)
    assert stranger.status_code in (303, 403)
    assert client.get(f"/api/evaluations/{evaluation_id}/crowd", headers=ADMIN).status_code == 404


def test_the_open_link_form_opens_the_link_and_a_visitor_withdraws_with_its_code(
    client, researcher, run_id
) -> None:
    evaluation_id = bare_evaluation(client, run_id=run_id)
    path = f"/evaluations/{evaluation_id}"
    saved = researcher.post(
        f"{path}/crowd", data=FORM | {"csrf_token": csrf_token(researcher, path)}
    )
    assert saved.status_code == 303 and saved.headers["location"] == f"{path}#crowd"
    link = client.get(f"/api/evaluations/{evaluation_id}/crowd", headers=ADMIN).json()
    assert link["enabled"] is True and link["max_participants"] == 5
    assert (link["time_limit_min"], link["decline_code"]) == (30, "LEFT-7")
    assert link["external_params"] == ["PROLIFIC_PID"] and link["consent_text"] is None
    html = researcher.get(path).text
    assert f'<code id="open-link">http://testserver/e/{link["slug"]}</code>' in html
    assert "0 of 5 joined" in html and "0 declined consent" in html
    assert re.search(r'id="time_limit_min"[^>]*value="30"', html) and audit(html) == []

    visitor = cookie_jar(client)
    joined = join(visitor, f"/e/{link['slug']}", params={"PROLIFIC_PID": "p-1"})
    assert joined.status_code == 303 and joined.headers["location"] == "/evaluate"
    assert visitor.get("/evaluate").status_code == 200
    assert "1 of 5 joined" in researcher.get(path).text
    token = _form(visitor, WITHDRAW)
    done = visitor.post(WITHDRAW, data={"csrf_token": token, "decision": "withdraw"})
    assert done.status_code == 303 and done.headers["location"] == "/evaluate/ended"
    ended = visitor.get("/evaluate/ended").text
    assert 'id="completion-code">LEFT-7<' in ended
    assert 'href="https://example.org/back?cc=LEFT-7"' in ended
    assert "0 of 5 joined" in researcher.get(path).text  # the seat was given back
    shared = visitor.post("/evaluate/share", data={"csrf_token": token, "share": "on"})
    assert shared.status_code == 303 and shared.headers["location"] == "/evaluate/ended"
    bearer = {"Authorization": f"Bearer {visitor.cookies['acv_evaluator']}"}
    refused = client.put("/api/evaluators/me/share-consent", json={"share": True}, headers=bearer)
    assert refused.status_code == 410 and "withdrew" in refused.json()["detail"]

    closed = FORM | {"enabled": "", "csrf_token": csrf_token(researcher, path)}
    assert researcher.post(f"{path}/crowd", data=closed).status_code == 303
    assert "Open link (closed)" in researcher.get(path).text


# --- in a real browser ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, int]]:
    """``acv serve`` without its run worker, holding a bare evaluation of one queued run;
    yields ``(base URL, evaluation id)``."""
    data_dir = tmp_path_factory.mktemp("acv-withdraw-data")
    env = clean_env(
        ACV_DATA_DIR=str(data_dir), ACV_ADMIN_TOKEN=SERVER_TOKEN, ACV_RUN_WORKER="false"
    )
    headers = {"Authorization": f"Bearer {SERVER_TOKEN}"}
    with (
        acv_serve(env, data_dir / "server.log") as base,
        httpx.Client(base_url=base, headers=headers, timeout=HTTP_TIMEOUT_S) as api,
    ):
        body = {"name": "Withdraw study", "env_id": "Hopper-v5", "n_candidates": 3, "seed": 2}
        study = api.post("/api/studies", json=body).json()
        wait_until_prepared(api, study["id"])
        run = {"study_id": study["id"], "teacher": "good", "algo": "bipars-em", "timesteps": 256}
        made = api.post("/api/runs", json=run | TINY)
        assert made.status_code == 202, made.text
        engine = make_engine(f"sqlite:///{data_dir / SQLITE_FILE}")
        try:  # bare_evaluation writes through ``app.state.runtime.sessions``: the server's DB
            runtime = SimpleNamespace(sessions=make_sessions(engine))
            app: Any = SimpleNamespace(app=SimpleNamespace(state=SimpleNamespace(runtime=runtime)))
            yield base, bare_evaluation(app, run_id=made.json()["id"])
        finally:
            engine.dispose()


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_the_withdraw_page_in_a_browser(
    served, browser: Browser, screens: Path, viewport: dict[str, int]
) -> None:
    base, evaluation_id = served
    where = "on a phone" if viewport == PHONE else "on a desktop"
    headers = {"Authorization": f"Bearer {SERVER_TOKEN}"}
    made = httpx.post(
        f"{base}/api/evaluations/{evaluation_id}/evaluators",
        json={"count": 1},
        headers=headers,
        timeout=HTTP_TIMEOUT_S,
    )
    assert made.status_code == 201, made.text
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=viewport)
    page.goto(made.json()[0]["invite_url"])
    page.wait_for_url(f"{base}/evaluate")
    page.click("#withdraw-link")
    page.wait_for_url(f"{base}{WITHDRAW}")
    expect(page.locator("h1")).to_have_text("Withdraw from this evaluation?")
    wait_until_still(page)
    assert fits_width(page), f"withdraw page {where}: wider than the window"
    assert_accessible(page, f"evaluator withdraw page {where}")
    page.screenshot(path=screens / f"evaluate-withdraw-{viewport['width']}.png", full_page=True)
    page.click("#withdraw")
    page.wait_for_url(f"{base}/evaluate/ended")
    expect(page.locator("h1")).to_have_text("You withdrew")
    wait_until_still(page)
    assert fits_width(page), f"ended page {where}: wider than the window"
    assert_accessible(page, f"evaluator ended page after withdrawing {where}")
    context.close()
    assert errors == []
