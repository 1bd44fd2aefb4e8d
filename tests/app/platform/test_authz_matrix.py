"""The authorisation matrix: every route of the app, asked by four callers.

Callers: anonymous, participant A (study S1, bracket finished), participant B (study S2),
and the researcher. Each API route is asked with bearer tokens and again with the role's
cookies (as the pages' scripts do); each page with cookies. :data:`RULES` says who may use
a route (first match wins, and anything unlisted is the researcher's alone), so a new route
is covered, deny-by-default, the moment it exists. Ids name real objects: A's study, match
and tree, and a finished run (a tiny one, trained once). Allowed means no 401/403, no login
redirect and no 5xx (a 409 from the handler is fine). Denied means 401/403 or a redirect to
the login page. A 404 counts as denied only where the researcher gets 404 for the same URL
too, or for a participant asking for what belongs to another participant or study (which
they are not told exists): a researcher route that lost its check cannot pass by "not
finding" a run.
"""

from __future__ import annotations

import base64
import logging
import re
from dataclasses import dataclass
from typing import Any

import pytest
from fastapi.routing import iter_route_contexts
from fastapi.testclient import TestClient
from sqlalchemy import text

from app.core import auth
from app.db import make_engine, make_sessions, upgrade, writing
from app.http.deps import AJAX_HEADER
from app.models import Experiment, ExperimentRun
from app.recruiting import members
from app.webhooks.outbox import Owner, emit
from tests.support.evaluations import bare_evaluation
from tests.support.postgres import BACKENDS, empty_database
from tests.support.runs import TINY, create_run, wait_run
from tests.support.studies import Player
from tests.support.web import ADMIN, ADMIN_TOKEN, browser, csrf_token

# postgres_only: a sweep of every route: validation and authorization are its subject, not storage.
pytestmark = pytest.mark.postgres_only

ANON, A, B, RESEARCHER = "anonymous", "participant A", "participant B", "researcher"
EVERYONE = frozenset({ANON, A, B, RESEARCHER})
#: (method or "*", path pattern, who may use it); first match wins.
RULES: list[tuple[str, str, frozenset[str]]] = [
    ("GET", r"/|/login|/p/\{token\}|/healthz|/openapi\.json|/docs", EVERYONE),
    ("*", r"/[sqe]/\{slug\}", EVERYONE),  # open links: anyone (CSRF on the consent post)
    ("*", r"/api/participants/me(/.*)?|/participate(/.*)?", frozenset({A, B})),
    ("*", r"/api/matches/\{match_id\}/label", frozenset({A})),  # A's match
    ("GET", r"/api/participants/\{participant_id\}/tree", frozenset({A, RESEARCHER})),
    (
        "GET",
        r"/api/studies/\{study_id\}/candidates/\{candidate_id\}/image",
        frozenset({A, RESEARCHER}),
    ),  # S1's images: not for B, who is in S2
    # Survey respondents' and evaluators' own routes: none of these four callers is one (A
    # and B hold a valid token of another kind, a participant's).
    ("*", r"/api/surveys/me(/.*)?|/survey|/r/\{token\}", frozenset()),
    ("*", r"/api/evaluators/me(/.*)?|/evaluate(/.*)?|/v/\{token\}", frozenset()),
    ("*", r"/.*", frozenset({RESEARCHER})),  # deny by default
]
#: Routes that take credentials rather than need them (CSRF and rate limits: see
#: ``test_security_headers``).
CREDENTIAL_FORMS = {("POST", "/login"), ("POST", "/logout")}
BODIES: dict[tuple[str, str], dict[str, Any]] = {
    ("POST", "/api/studies"): {"name": "authz", "env_id": "Hopper-v5", "n_candidates": 2},
    ("POST", "/api/studies/{study_id}/participants/batch"): {"count": 1},
    ("POST", "/studies"): {
        "name": "authz",
        "env_id": "Hopper-v5",
        "n_candidates": "2",
        "p": "0.9",
        "seed": "0",
        "sampling": "uniform",
        "instructions": "",
    },
    ("POST", "/studies/{study_id}/participants"): {"count": "1"},
    # the consent form's buttons: declining stores only a count, for anyone
    ("POST", "/s/{slug}"): {"decision": "decline"},
    ("POST", "/q/{slug}"): {"decision": "decline"},
    ("POST", "/e/{slug}"): {"decision": "decline"},
}

#: Query strings of routes that need one to name something real.
QUERIES = {("GET", "/runs/new"): "?study_id={study_id}"}


@dataclass(frozen=True)
class Caller:
    """One role: its API headers and its browser cookies."""

    name: str
    headers: dict[str, str]
    cookies: dict[str, str]


def rule_for(method: str, path: str) -> frozenset[str]:
    for rule_method, pattern, who in RULES:
        if rule_method in ("*", method) and re.fullmatch(pattern, path):
            return who
    raise AssertionError("unreachable: the last rule matches everything")


def app_routes(app) -> list[tuple[str, str]]:
    """(method, path) of every route, reads first (writes change the state reads see)."""
    pairs = {
        (m, r.path)
        for r in iter_route_contexts(app.routes)
        if r.methods
        for m in r.methods
        if m != "HEAD"
    }
    return sorted(pairs - CREDENTIAL_FORMS, key=lambda p: (p[0] != "GET", p[1], p[0]))


def denied(response, *, may_hide: bool) -> bool:
    """Refused: 401, 403 or a login redirect; also 404 where ``may_hide``."""
    if response.status_code in (401, 403) or (may_hide and response.status_code == 404):
        return True
    return response.status_code in (302, 303, 307) and response.headers["location"].startswith(
        "/login"
    )


def allowed(response) -> bool:
    redirected = response.status_code in (302, 303, 307) and response.headers[
        "location"
    ].startswith("/login")
    return response.status_code < 500 and response.status_code not in (401, 403) and not redirected


@pytest.fixture(scope="module")
def world(client: TestClient, study: dict[str, Any], make_study) -> dict[str, Any]:
    """S1 with participant A (finished), S2 with participant B, and the four callers."""
    other = make_study(name="other study", seed=4)
    a, b = (_invite(client, sid) for sid in (study["id"], other["id"]))
    assert a.play() == 4
    page = browser(client)
    form_token = csrf_token(page)
    csrf = {"acv_csrf": page.cookies["acv_csrf"]}
    login = page.post("/login", data={"csrf_token": form_token, "token": ADMIN_TOKEN})
    callers = [
        Caller(ANON, {}, csrf),
        Caller(B, b.headers, csrf | {"acv_participant": b.token}),
        Caller(RESEARCHER, ADMIN, csrf | {"acv_researcher": login.cookies["acv_researcher"]}),
        Caller(A, a.headers, csrf | {"acv_participant": a.token}),
    ]
    last_match = client.get("/api/participants/me/bracket", headers=a.headers).json()
    final = last_match["rounds"][-1][0]
    run_id = create_run(
        client,
        study_id=study["id"],
        teacher="good",
        algo="bipars-em",
        timesteps=256,
        checkpoint_every=128,
        **TINY,
    )
    assert wait_run(client, run_id)["status"] == "succeeded"  # every run route has data
    tree = {"kind": "participant", "participant_id": a.id}
    survey = client.post(
        "/api/surveys",
        headers=ADMIN,
        json={"name": "authz", "stimuli": [{"tree1": tree, "tree2": tree}]},
    ).json()
    link = client.put(
        f"/api/studies/{study['id']}/crowd",
        headers=ADMIN,
        json={"enabled": True, "max_participants": 100},
    ).json()
    survey_link = client.put(
        f"/api/surveys/{survey['id']}/crowd",
        headers=ADMIN,
        json={"enabled": True, "max_participants": 100},
    ).json()
    gold_item = client.post(
        f"/api/studies/{study['id']}/gold", headers=ADMIN, json={"a": 0, "b": 1, "answer": 0}
    ).json()
    webhook = client.post(  # to 127.0.0.1 (the tests' setting); port 9 listens to nothing
        "/api/webhooks", headers=ADMIN, json={"study_id": study["id"], "url": "http://127.0.0.1:9/"}
    ).json()
    with client.app.state.runtime.sessions() as session, writing(session):
        emit(session, owner=Owner("study", study["id"]), type_="test", subject=None, data=dict)
    [event] = client.get(f"/api/webhooks/{webhook['id']}/events", headers=ADMIN).json()
    evaluation_id = bare_evaluation(client, run_id=run_id)
    params = {
        "experiment_id": _experiment(client, study_id=study["id"], run_id=run_id),
        "survey_slug": survey_link["slug"],  # ``slug`` in /q/{slug}
        "evaluation_slug": _evaluation_link(client, evaluation_id),  # and in /e/{slug}
        "study_id": study["id"],
        "candidate_id": 0,
        "participant_id": a.id,
        "slug": link["slug"],
        "token": a.token,
        "match_id": final["match_id"],
        "run_id": run_id,
        "which": "human",
        "fmt": "svg",
        "survey_id": survey["id"],
        "position": 1,
        "webhook_id": webhook["id"],
        "event_id": event["event_id"],
        "item_id": gold_item["id"],
        "evaluation_id": evaluation_id,
        "key": "no-such-pair",
        "side": "left",
        "kind": "still",
        "place": "first",  # an evaluator's bracket reminder picture
    }
    return {
        "callers": callers,
        "params": params,
        "form_token": form_token,
        "a": a,
        "b": b,
        "label": {"winner": final["winner"]},
    }


def _experiment(client: TestClient, *, study_id: int, run_id: int) -> int:
    """An experiment whose only run is the world's trained one (no new runs to train)."""
    with client.app.state.runtime.sessions() as session, session.begin():
        experiment = Experiment(study_id=study_id, spec={}, seeds=[0], pilot_seeds=[])
        session.add(experiment)
        session.flush()
        session.add(ExperimentRun(experiment_id=experiment.id, run_id=run_id, role="advised"))
        return experiment.id


def _evaluation_link(client: TestClient, evaluation_id: int) -> str:
    """The open link of the world's evaluation, behind a consent page."""
    link = client.put(
        f"/api/evaluations/{evaluation_id}/crowd",
        headers=ADMIN,
        json={"enabled": True, "max_participants": 100, "consent_text": "Agree?"},
    )
    assert link.status_code == 200, link.text
    return link.json()["slug"]


def _invite(client: TestClient, study_id: int) -> Player:
    body = client.post(f"/api/studies/{study_id}/participants", headers=ADMIN).json()
    return Player(client, body["id"], body["token"], body["invite_url"])


def _ask(
    client: TestClient,
    method: str,
    path: str,
    caller: Caller,
    world: dict[str, Any],
    *,
    cookies: bool,
):
    params = dict(world["params"])
    if path.startswith("/q/"):  # a survey's open link
        params["slug"] = params["survey_slug"]
    if path.startswith("/e/"):  # an evaluation's
        params["slug"] = params["evaluation_slug"]
    url = path.format(**params) + QUERIES.get((method, path), "").format(**params)
    body = BODIES.get((method, path), world["label"] if "label" in path else None)
    headers = {} if cookies else dict(caller.headers)
    if cookies:
        headers["Cookie"] = "; ".join(f"{k}={v}" for k, v in caller.cookies.items())
        headers |= dict([AJAX_HEADER])  # what the pages' scripts send
    page = not path.startswith("/api/")
    kwargs: dict[str, Any] = {"headers": headers}
    if method == "POST" and page:
        kwargs["data"] = {"csrf_token": world["form_token"], **(body or {})}
    elif method == "POST":
        kwargs["json"] = body or {}
    response = client.request(method, url, **kwargs)
    client.cookies.clear()  # each request carries exactly the caller's cookies
    return response


@pytest.mark.training  # the world has a trained run
def test_every_route_is_in_the_matrix_and_enforced(client, world) -> None:
    asker = TestClient(client.app, follow_redirects=False)
    failures = []
    for method, path in app_routes(client.app):
        missing = set(re.findall(r"\{(\w+)", path)) - set(world["params"])
        assert not missing, f"{method} {path}: give the matrix a value for {missing}"
        who = rule_for(method, path)
        modes = (True,) if not path.startswith("/api/") else (False, True)
        researcher_first = sorted(world["callers"], key=lambda c: c.name != RESEARCHER)
        for cookies in modes:
            missing = False  # the researcher gets 404: the URL names nothing
            for caller in researcher_first:
                response = _ask(asker, method, path, caller, world, cookies=cookies)
                if caller.name == RESEARCHER:
                    missing = response.status_code == 404
                if who == EVERYONE:  # e.g. ``/`` sends strangers to the login page
                    ok = response.status_code < 400
                else:
                    others = caller.name in (A, B) and bool(who & {A, B})  # not theirs
                    ok = (
                        allowed(response)
                        if caller.name in who
                        else denied(response, may_hide=missing or others)
                    )
                if not ok:
                    failures.append(
                        f"{method} {path} as {caller.name} "
                        f"({'cookie' if cookies else 'bearer'}): "
                        f"{response.status_code} {response.text[:120]}"
                    )
    assert failures == [], "\n".join(failures)


@pytest.mark.training
def test_participants_see_only_their_own_bracket(client, world) -> None:
    a, b = world["a"], world["b"]
    assert client.get("/api/participants/me", headers=b.headers).json()["id"] == b.id
    bracket = client.get("/api/participants/me/bracket", headers=b.headers).json()
    b_matches = {c["match_id"] for r in bracket["rounds"] for c in r if c["match_id"]}
    assert world["params"]["match_id"] not in b_matches
    response = client.post(
        f"/api/matches/{world['params']['match_id']}/label", headers=b.headers, json={"winner": 0}
    )
    assert response.status_code == 404
    assert client.get(f"/api/participants/{a.id}/tree", headers=b.headers).status_code == 403


def test_invite_tokens_are_unguessable(client, study) -> None:
    people = client.post(
        f"/api/studies/{study['id']}/participants/batch", headers=ADMIN, json={"count": 200}
    ).json()
    tokens = [p["token"] for p in people]
    assert len(set(tokens)) == len(tokens)
    for token in tokens:
        assert re.fullmatch(r"[A-Za-z0-9_-]+", token)
        assert len(base64.urlsafe_b64decode(token + "=" * (-len(token) % 4))) * 8 >= 128


def test_tokens_are_compared_in_constant_time(client, invite, monkeypatch) -> None:
    """Both secrets reach :func:`secrets.compare_digest` (the invite token after a lookup
    by its hash, which tells an attacker nothing about the token)."""
    compared: list[bytes] = []
    real = auth.secrets.compare_digest

    def spy(x: bytes, y: bytes) -> bool:
        compared.append(y)
        return real(x, y)

    player = invite()
    monkeypatch.setattr(auth.secrets, "compare_digest", spy)
    assert client.get("/api/participants/me", headers=player.headers).status_code == 200
    assert player.token.encode() in compared
    assert client.get("/api/studies", headers=ADMIN).status_code == 200
    assert ADMIN_TOKEN.encode() in compared


@pytest.mark.training
def test_admin_token_never_appears_in_pages_or_logs(client, world, caplog) -> None:
    researcher = world["callers"][2]
    asker = TestClient(client.app, follow_redirects=False)
    with caplog.at_level(logging.DEBUG):
        for method, path in app_routes(client.app):
            if method == "GET":
                for cookies in (False, True):
                    response = _ask(asker, method, path, researcher, world, cookies=cookies)
                    assert ADMIN_TOKEN not in response.text, path
        asker.post(
            "/login",
            data={"csrf_token": world["form_token"], "token": ADMIN_TOKEN[:-1]},
            headers={"Cookie": f"acv_csrf={researcher.cookies['acv_csrf']}"},
        )
    assert [r.getMessage() for r in caplog.records if ADMIN_TOKEN[:-1] in r.getMessage()] == []


@pytest.mark.parametrize("backend", BACKENDS)
def test_invite_links_from_before_the_token_hash_still_work(
    request, tmp_path, backend: str
) -> None:
    """Migration 0003 hashes the tokens of existing participants, and keeps their matches
    (no table copy whose drop would cascade)."""
    url = empty_database(request, tmp_path, backend)
    upgrade(url, "0002")
    engine = make_engine(url)
    token = auth.new_token()
    with engine.begin() as conn:
        conn.execute(
            text(
                "INSERT INTO studies (id, name, env_id, n_candidates, p, seed, sampling, "
                "instructions, status, created_at) VALUES (1, 's', 'Hopper-v5', 2, 0.9, 0, "
                "'uniform', '', 'ready', CURRENT_TIMESTAMP)"
            )
        )
        conn.execute(
            text(
                "INSERT INTO participants (id, study_id, token, created_at) "
                "VALUES (1, 1, :token, CURRENT_TIMESTAMP)"
            ),
            {"token": token},
        )
        conn.execute(
            text(
                "INSERT INTO matches (id, participant_id, round, slot, a, b, "
                "created_at) VALUES (1, 1, 1, 0, 0, 1, CURRENT_TIMESTAMP)"
            )
        )
    engine.dispose()
    upgrade(url)
    engine = make_engine(url)
    try:
        with make_sessions(engine)() as session:
            assert members.member_by_token(session, members.STUDY, token=token).id == 1
            assert session.scalar(text("SELECT count(*) FROM matches")) == 1
    finally:
        engine.dispose()
