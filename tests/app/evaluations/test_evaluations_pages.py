"""Agent evaluation pages without a browser (issue 41 §1): the researcher creates an
evaluation from the experiment page and invites evaluators on its page; an evaluator's invite
link sets their cookie, the pair pages are blind plain forms that move on, the thank-you page
ends them; an ended evaluator is told so; bad form input is a 4xx page. On both databases.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from datetime import timedelta
from typing import Any
from urllib.parse import parse_qsl, urlsplit

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import update

from app.core.auth import EVALUATOR_COOKIE
from app.models import Member, utcnow
from tests.support.evaluations import evaluable_experiment, wait_evaluation
from tests.support.runs import run_app
from tests.support.studies import new_study
from tests.support.web import (
    ADMIN,
    ADMIN_TOKEN,
    CSRF_RE,
    audit,
    browser,
    csrf_token,
    logged_in,
    shown_again,
)

# postgres_only: pages are the subject, not storage.
pytestmark = pytest.mark.postgres_only

PAIRS = 3
#: Every URL in a page: where its pictures, links and forms point, and its data attributes.
URL_ATTRS = re.compile(r'(?:src|href|action|data-[a-z-]+)="([^"]*)"')
INVITE = re.compile(r'value="http://testserver/v/([A-Za-z0-9_-]+)"')


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def researcher(client: TestClient) -> TestClient:
    return logged_in(client)


@pytest.fixture(scope="module")
def experiment(client: TestClient) -> dict[str, Any]:
    study = new_study(client, n_candidates=5, seed=21)
    return evaluable_experiment(client, study["id"], seeds=2)


def _create(researcher: TestClient, experiment_id: int, **form: str) -> Any:
    body = {"evaluator_kind": "others", "stimulus": "clip", "pairs_per_evaluator": str(PAIRS)}
    token = csrf_token(researcher, f"/experiments/{experiment_id}")
    return researcher.post(
        f"/experiments/{experiment_id}/evaluations", data=body | form | {"csrf_token": token}
    )


@pytest.fixture(scope="module")
def evaluation(client, researcher, experiment) -> dict[str, Any]:
    """An evaluation made by the experiment page's form, once its clips are rendered."""
    response = _create(researcher, experiment["id"])
    assert response.status_code == 303, response.text
    assert re.fullmatch(r"/evaluations/\d+", location := response.headers["location"])
    return wait_evaluation(client, int(location.rsplit("/", 1)[1]), clips=True)


@pytest.fixture(scope="module")
def run_ids(client, evaluation) -> set[str]:
    result = client.get(f"/api/evaluations/{evaluation['id']}/result", headers=ADMIN).json()
    return {str(s["run_id"]) for s in result["slots"]}


def _invite(researcher: TestClient, evaluation_id: int, count: int = 1) -> list[str]:
    """Invite by the evaluation page's form; the new evaluators' tokens."""
    page = f"/evaluations/{evaluation_id}"
    before = INVITE.findall(researcher.get(page).text)
    data = {"count": str(count), "csrf_token": csrf_token(researcher, page)}
    response = researcher.post(f"{page}/evaluators", data=data)
    assert response.status_code == 303, response.text
    assert response.headers["location"] == f"{page}?invited={count}#evaluators"
    html = researcher.get(response.headers["location"]).text
    assert f"Invited {count} new evaluator" in html
    return INVITE.findall(html)[len(before) :]


def _evaluator(client: TestClient, token: str) -> TestClient:
    person = browser(client)
    assert person.get(f"/v/{token}").status_code == 303
    return person


def _answer(person: TestClient, answer: str, **fields: str) -> tuple[str, Any]:
    """Answer the pair shown now by its form (``fields`` override what it posts); the pair's
    key and the answer's response."""
    html = person.get("/evaluate/pair").text
    key = re.search(r'name="key" value="([^"]+)"', html)
    token = CSRF_RE.search(html)
    assert key and token, html
    data = {"csrf_token": token.group(1), "key": key.group(1), "choice": answer}
    shown_at = re.search(r'name="shown_at" value="(\d+)"', html)
    assert shown_at
    data |= {"stimulus": "still", "shown_at": shown_at.group(1)} | fields
    return key.group(1), person.post("/evaluate/pair", data=data)


def test_researcher_pages_send_strangers_to_login(client, evaluation) -> None:
    stranger = browser(client)
    response = stranger.get(f"/evaluations/{evaluation['id']}")
    assert response.status_code == 303
    assert response.headers["location"].startswith("/login?next=/evaluations/")


def test_the_experiment_page_lists_and_creates_evaluations(
    researcher, experiment, evaluation
) -> None:
    html = researcher.get(f"/experiments/{experiment['id']}").text
    assert 'id="evaluation-form"' in html and f'href="/evaluations/{evaluation["id"]}"' in html
    assert '<option value="others" selected>' in html and '<option value="clip" selected>' in html
    assert re.search(r'name="pairs_per_evaluator"[^>]*value="20"', html)  # the defaults
    page = researcher.get(f"/evaluations/{evaluation['id']}")
    assert page.status_code == 200 and 'data-status="ready"' in page.text
    assert 'id="needed">not computed yet' not in page.text  # the design's power is shown
    assert 'data-clips="ready"' in page.text and "Which agent follows the instruction" in page.text


def test_the_invite_link_sets_the_cookie_and_redirects(client, researcher, evaluation) -> None:
    (token,) = _invite(researcher, evaluation["id"])
    person = browser(client)
    assert person.get("/evaluate").status_code == 401  # no invitation in this browser yet
    response = person.get(f"/v/{token}")
    assert response.status_code == 303 and response.headers["location"] == "/evaluate"
    cookie = response.headers["set-cookie"]
    assert f"{EVALUATOR_COOKIE}={token}" in cookie
    assert "HttpOnly" in cookie and "SameSite=lax" in cookie
    page = person.get("/evaluate")
    assert (
        page.status_code == 200
        and 'id="start"' in page.text
        and "Pick the taller one." in page.text
    )
    assert token not in page.text
    assert browser(client).get("/v/not-a-real-token").status_code == 404


def test_pairs_are_blind_move_on_and_end_with_thanks(
    client, researcher, evaluation, run_ids
) -> None:
    (token,) = _invite(researcher, evaluation["id"])
    person = _evaluator(client, token)
    keys = []
    for i, choice in enumerate(("left", "tie", "right")):
        html = person.get("/evaluate/pair").text
        _pictures_are_blind(html, run_ids, evaluation)
        assert f"Pair {i + 1} of {PAIRS}" in html and audit(html) == []
        key, response = _answer(person, choice, stimulus="clip" if i else "still")
        assert response.status_code == 303 and response.headers["location"] == "/evaluate/pair"
        keys.append(key)
    assert len(set(keys)) == PAIRS  # each answer moved on to another pair
    done = person.get("/evaluate/pair")
    assert done.status_code == 303 and done.headers["location"] == "/evaluate/thanks"
    thanks = person.get("/evaluate/thanks")
    assert thanks.status_code == 200 and f"You answered all {PAIRS} pairs" in thanks.text
    assert person.get("/evaluate").headers["location"] == "/evaluate/thanks"
    answers = client.get(f"/api/evaluations/{evaluation['id']}/answers.csv", headers=ADMIN).text
    rows = [line for line in answers.splitlines()[1:] if line]
    assert len(rows) >= PAIRS
    assert {",still,", ",clip,"} <= {m.group(0) for m in re.finditer(r",(still|clip),", answers)}


def _pictures_are_blind(html: str, run_ids: set[str], evaluation: dict[str, Any]) -> None:
    """Two pictures under the pair's key; no run id as a path segment or query value."""
    key = re.search(r'data-key="([^"]+)"', html)
    assert key
    pictures = re.findall(r'<img id="img-(left|right)" src="([^"]+)" alt="(\w+) agent"', html)
    assert [(side, alt) for side, _, alt in pictures] == [("left", "left"), ("right", "right")]
    for _, src, _ in pictures:
        assert src.startswith(f"/api/evaluators/me/pairs/{key.group(1)}/")
    assert html.count("data-clip=") == 2  # the clips are ready: the script plays them
    for url in URL_ATTRS.findall(html):
        parts = urlsplit(url)
        values = set(parts.path.split("/")) | {v for _, v in parse_qsl(parts.query)}
        assert not values & run_ids, url
    lowered = html.lower()
    assert "advised" not in lowered and "baseline" not in lowered
    assert evaluation["name"] not in html


def test_the_researcher_page_shows_the_answer(client, researcher, evaluation) -> None:
    (token,) = _invite(researcher, evaluation["id"])
    person = _evaluator(client, token)
    for _ in range(PAIRS):
        assert _answer(person, "left")[1].status_code == 303
    html = researcher.get(f"/evaluations/{evaluation['id']}").text
    result = client.get(f"/api/evaluations/{evaluation['id']}/result", headers=ADMIN).json()
    shown = result["outcome"] if result["final"] else "interim"
    assert f'data-outcome="{shown}"' in html and result["sentence"] in html
    assert f"{result['n_answers']} · {result['n_evaluators']}" in html
    assert "Followed your tree" in html and "does what you asked" in html
    assert f'href="/api/evaluations/{evaluation["id"]}/answers.csv"' in html
    assert f"{PAIRS}/{PAIRS} · finished" in html
    for path in (f"/evaluations/{evaluation['id']}", "/evaluate/pair", "/evaluate/thanks"):
        page = researcher.get(path) if path.startswith("/evaluations") else person.get(path)
        assert "script-src 'self'" in page.headers["content-security-policy"]
        assert ADMIN_TOKEN not in page.text and audit(page.text) == []


@pytest.mark.parametrize(
    ("form", "status", "says", "invalid"),
    [
        ({"pairs_per_evaluator": "0"}, 422, "Pairs per evaluator", "pairs"),
        ({"pairs_per_evaluator": "many"}, 422, "Pairs per evaluator", "pairs"),
        ({"pairs_per_evaluator": "201"}, 422, "Pairs per evaluator", "pairs"),
        ({"stimulus": "video"}, 422, "What they see", "stimulus"),
        ({"evaluator_kind": "robot"}, 422, "Who answers", "kind"),
        ({"gold_gate": "7"}, 422, "Gold gate", "gold-gate"),
        ({"evaluator_kind": "advisor"}, 409, "one participant&#39;s tree", None),
        ({"show_bracket": "on"}, 422, "advisor only", None),
    ],
)
def test_a_bad_design_shows_the_form_again(
    researcher, experiment, form, status, says, invalid
) -> None:
    """The form again, with what was sent and what is wrong; the field it is about (none:
    the design as a whole) is marked invalid and described by the error."""
    response = _create(researcher, experiment["id"], **form)
    assert response.status_code == status, response.text
    assert says in response.text and 'id="evaluation-form"' in response.text
    kept = {"evaluator_kind": "others", "stimulus": "clip"} | form  # the form keeps what was sent
    assert re.search(
        rf'name="pairs_per_evaluator"[^>]*value="{form.get("pairs_per_evaluator", PAIRS)}"',
        response.text,
    )
    for name in ("evaluator_kind", "stimulus"):
        if kept[name] in ("others", "advisor", "clip", "still"):
            assert f'<option value="{kept[name]}" selected>' in response.text
    assert 'role="alert"' in response.text
    marked = re.findall(r'id="evaluation-([\w-]+)"[^>]*aria-invalid="true"', response.text)
    assert marked == ([invalid] if invalid else [])
    if invalid:
        assert re.search(rf'id="evaluation-{invalid}"[^>]*evaluation-error"', response.text)


def test_bad_form_posts_are_4xx_pages(client, researcher, experiment, evaluation) -> None:
    page = f"/evaluations/{evaluation['id']}/evaluators"
    token = csrf_token(researcher, f"/evaluations/{evaluation['id']}")
    before = len(INVITE.findall(researcher.get(f"/evaluations/{evaluation['id']}").text))
    for count in ("x", "0", "1_0"):
        typed = {"count": count, "name": "session 3"}
        refused = researcher.post(page, data={**typed, "csrf_token": token})
        assert refused.status_code == 422 and "<title>Evaluation #" in refused.text
        shown_again(refused.text, "invite", typed, {"count": "count", "invite-name": "name"})
    assert len(INVITE.findall(researcher.get(f"/evaluations/{evaluation['id']}").text)) == before
    assert researcher.post(page, data={"count": "1"}).status_code == 403  # no CSRF token
    create = f"/experiments/{experiment['id']}/evaluations"
    assert researcher.post(create, data={"pairs_per_evaluator": "3"}).status_code == 403
    missing = researcher.post(
        "/experiments/999999/evaluations", data={"csrf_token": token, "pairs_per_evaluator": "3"}
    )
    assert missing.status_code == 404
    (invited,) = _invite(researcher, evaluation["id"])
    person = _evaluator(client, invited)
    for fields, status in (
        ({"choice": "up"}, 422),
        ({"stimulus": "video"}, 422),
        ({"key": "not-their-pair"}, 404),
        ({"key": "<script>"}, 422),
        ({"csrf_token": "forged"}, 403),
    ):
        response = _answer(person, "left", **fields)[1]
        assert response.status_code == status, (fields, response.text)
        assert response.headers["content-type"].startswith("text/html")


def test_an_answer_given_otherwise_is_a_409_page(client, researcher, evaluation) -> None:
    (token,) = _invite(researcher, evaluation["id"])
    person = _evaluator(client, token)
    key, first = _answer(person, "left")
    assert first.status_code == 303
    again = _answer(person, "right", key=key)[1]
    assert again.status_code == 409 and "Already answered" in again.text
    assert 'href="/evaluate/pair"' in again.text


@pytest.mark.parametrize("ending", ["timed_out", "withdrawn"])
def test_an_ended_evaluator_is_told(client, researcher, evaluation, ending) -> None:
    (token,) = _invite(researcher, evaluation["id"])
    person = _evaluator(client, token)
    html = person.get("/evaluate/pair").text  # the form, before the time runs out
    moment = utcnow() - timedelta(minutes=1)
    values = {"deadline_at": moment} if ending == "timed_out" else {"withdrawn_at": moment}
    with client.app.state.runtime.sessions() as session:
        session.execute(update(Member).where(Member.token == token).values(**values))
        session.commit()
    for path in ("/evaluate", "/evaluate/pair", "/evaluate/thanks"):
        response = person.get(path)
        assert response.headers["location"] == "/evaluate/ended", path
    title = "Your time is over" if ending == "timed_out" else "You withdrew"
    assert title in person.get("/evaluate/ended").text
    key = re.search(r'name="key" value="([^"]+)"', html)
    token_field = CSRF_RE.search(html)
    assert key and token_field
    data = {"csrf_token": token_field.group(1), "key": key.group(1), "choice": "left"}
    posted = person.post("/evaluate/pair", data=data)
    assert posted.status_code == 303 and posted.headers["location"] == "/evaluate/ended"
