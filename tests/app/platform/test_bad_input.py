"""Bad input on every route: malformed ids, huge bodies, wrong content types, non-UTF-8 bytes,
and path traversal (``..`` and its encodings) in URLs and in stored file paths. Each gets a
4xx answer, and no file outside the data dir (or the static dir) is ever read. Corrupt
checkpoint files and stored trees are refused with a message that names the problem.

Runs on SQLite and PostgreSQL (the ``client`` fixture).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.routing import iter_route_contexts
from fastapi.testclient import TestClient
from sqlalchemy import update

from app.db import make_engine, make_sessions
from app.middleware import MAX_BODY_BYTES
from app.models import Candidate, Run, RunCheckpoint
from app.runs import artefacts
from engine.rl.checkpoint import checkpoint_path
from tests.support.runs import run_app
from tests.support.web import ADMIN, ADMIN_TOKEN, audit

CANARY = "acv-canary-outside-the-data-dir"
MALFORMED_IDS = [
    "abc",
    "0",
    "-1",
    "1.5",
    "1e3",
    "99999999999999999999",
    "%00",
    "%ff",
    "%2e%2e",
    "..%2f..%2fetc%2fpasswd",
    "%E2%80%AE1",
    "0x10",
    "1_000",
]
TRAVERSALS = [
    "/static/../app/settings.py",
    "/static/%2e%2e/app/settings.py",
    "/static/..%2fapp%2fsettings.py",
    "/static/%2e%2e%2f%2e%2e%2f{canary}",
    "/static/..%5c..%5c{canary}",
    "/static//{canary_abs}",
    "/static/%2f{canary_abs}",
    "/static/js/%2e%2e/%2e%2e/%2e%2e/{canary}",
    "/static/%252e%252e/app/settings.py",
    "/api/studies/{sid}/candidates/..%2f..%2f{canary}/image",
    "/api/studies/{sid}/candidates/0/image?size=..%2f..%2f{canary}",
    "/p/..%2f..%2f{canary}",
    "/p/%2e%2e",
    "/studies/..%2f..%2f{canary}",
    "//{canary_abs}",
    "/studies/{sid}/participants/..%2f..%2f{canary}/tree.json",
]


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    """This module's one app, without its training worker (and so without its idle backfill):
    runs stay as the tests leave them, and only a test's own backfill judges their
    checkpoints. (With a worker beside it, its backfill could judge a corrupt checkpoint
    first, and the test's own backfill would then find nothing to do.)"""
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def canary(settings) -> Path:
    """A secret file just outside the data dir, which no request may read."""
    path = settings.data_dir.parent / f"{settings.data_dir.name}-canary.txt"
    path.write_text(CANARY)
    return path


@pytest.fixture(scope="module")
def researcher_page(client: TestClient) -> TestClient:
    page = TestClient(client.app, follow_redirects=False)
    form = page.get("/login").text
    token = re.search(r'name="csrf_token" value="([^"]+)"', form).group(1)
    assert page.post("/login", data={"csrf_token": token, "token": ADMIN_TOKEN}).status_code == 303
    return page


def _routes_with_ids(client: TestClient) -> list[tuple[str, str]]:
    return sorted(
        {
            (m, r.path)
            for r in iter_route_contexts(client.app.routes)
            if r.methods
            for m in r.methods
            if m != "HEAD" and "{" in r.path
        }
    )


def _clean(response) -> None:
    assert 400 <= response.status_code < 500, (
        response.url,
        response.status_code,
        response.text[:300],
    )
    assert CANARY not in response.text and "Traceback" not in response.text


def test_malformed_ids_on_every_route_are_4xx(client, researcher_page, invite) -> None:
    player = invite()
    for method, path in _routes_with_ids(client):
        for bad in MALFORMED_IDS:
            url = re.sub(r"\{\w+\}", bad, path)
            if path.startswith("/api/"):
                for headers in (ADMIN, player.headers):
                    _clean(client.request(method, url, headers=headers, json={"winner": 0}))
            else:
                _clean(researcher_page.request(method, url))


@pytest.mark.parametrize("template", TRAVERSALS)
def test_path_traversal_reads_nothing_outside(
    client, researcher_page, study, canary, template: str
) -> None:
    url = template.format(sid=study["id"], canary=canary.name, canary_abs=str(canary).lstrip("/"))
    for asker, headers in ((client, ADMIN), (researcher_page, {})):
        response = asker.get(url, headers=headers)
        assert response.status_code in (400, 404, 422) or (
            response.status_code in (303, 307) and "canary" not in response.headers["location"]
        ), (url, response.status_code)
        assert CANARY not in response.text and "BaseSettings" not in response.text


@pytest.mark.parametrize(
    "stored", ["../{canary}", "{canary_abs}", "images/../../{canary}", "images/link.jpg"]
)
def test_stored_image_paths_outside_the_data_dir_are_refused(
    client, settings, study, canary, stored: str
) -> None:
    """A path in the database (tampered with, or a symlink planted in the data dir) is
    never followed out of the data dir."""
    link = settings.data_dir / "images" / "link.jpg"
    link.unlink(missing_ok=True)
    link.symlink_to(canary)
    stored = stored.format(canary=canary.name, canary_abs=str(canary))
    engine = make_engine(settings.sqlalchemy_url)
    with make_sessions(engine)() as session:
        original = session.get(Candidate, (study["id"], 1)).image_path
        session.execute(
            update(Candidate)
            .where(Candidate.study_id == study["id"], Candidate.id == 1)
            .values(image_path=stored)
        )
        session.commit()
    try:
        _clean(client.get(f"/api/studies/{study['id']}/candidates/1/image", headers=ADMIN))
    finally:
        with make_sessions(engine)() as session:
            session.execute(
                update(Candidate)
                .where(Candidate.study_id == study["id"], Candidate.id == 1)
                .values(image_path=original)
            )
            session.commit()
        engine.dispose()
    assert (
        client.get(f"/api/studies/{study['id']}/candidates/1/image", headers=ADMIN).status_code
        == 200
    )


BODY_CASES: list[tuple[str, dict[str, Any]]] = [
    ("text/plain", {"content": b'{"name": "x", "n_candidates": 2}'}),
    ("application/x-www-form-urlencoded", {"content": b"name=x&n_candidates=2"}),
    ("application/xml", {"content": b"<study><name>x</name></study>"}),
    ("multipart/form-data; boundary=zz", {"content": b"--zz\r\nbroken"}),
    ("application/json", {"content": b"\xff\xfe\x00{\xc3\x28}"}),  # not UTF-8
    ("application/json; charset=latin-1", {"content": '{"name": "\xe9"}'.encode("latin-1")}),
    ("application/json", {"content": b'{"name": "x", "n_candidates": 2' + b" " * 1000}),
    ("application/json", {"content": b"[" * 50_000 + b"]" * 50_000}),  # deep nesting
    ("application/json", {"content": b'{"name": "\\ud800", "n_candidates": 2}'}),
    (None, {"content": b"\x00\x01\x02"}),
]


@pytest.mark.parametrize(("content_type", "body"), BODY_CASES)
@pytest.mark.parametrize(
    "path", ["/api/studies", "/api/studies/{sid}/participants/batch", "/api/matches/1/label"]
)
def test_wrong_content_types_and_bytes_are_4xx(
    client, study, invite, path: str, content_type: str | None, body: dict[str, Any]
) -> None:
    headers = ADMIN if "studies" in path else invite().headers
    if content_type:
        headers = headers | {"Content-Type": content_type}
    _clean(client.post(path.format(sid=study["id"]), headers=headers, **body))


@pytest.mark.parametrize(
    "content_type", ["application/json", "text/plain", "multipart/form-data; boundary=zz", None]
)
def test_form_posts_with_odd_bodies_are_4xx(researcher_page, study, content_type) -> None:
    headers = {"Content-Type": content_type} if content_type else {}
    for path in ("/login", "/logout", "/studies", f"/studies/{study['id']}/participants"):
        for content in (b"\xff\xfe=\xff", b'{"csrf_token": 1}', b"a=" + b"%" * 3000):
            _clean(researcher_page.post(path, content=content, headers=headers))


def _attr(tag: str, name: str) -> str | None:
    found = re.search(rf'\b{name}="([^"]*)"', tag)
    return found.group(1) if found else None


def page_forms(page: TestClient, study_id: int) -> list[tuple[str, dict[str, str], list[str]]]:
    """``(action, fields as the page fills them, integer fields)`` of the researcher's forms
    with an integer field (number inputs, numeric hidden ones); empty text fields get a
    value, so that only the integer field is wrong."""
    forms = []
    for path in ("/studies/new", f"/runs/new?study_id={study_id}", f"/studies/{study_id}"):
        for attrs, body in re.findall(
            r'<form ([^>]*method="post"[^>]*)>(.*?)</form>', page.get(path).text, re.DOTALL
        ):
            fields, integers = {}, []
            for tag in re.findall(r"<input [^>]*name=[^>]*>", body):
                name, value, kind = _attr(tag, "name"), _attr(tag, "value"), _attr(tag, "type")
                fields[name] = value or ("x" if kind in (None, "text") else "")
                value = value or ""
                if (kind == "number" and _attr(tag, "step") != "any") or (
                    kind == "hidden" and value.isdigit()
                ):
                    integers.append(name)
            for name, options in re.findall(
                r'<select [^>]*name="([^"]+)"[^>]*>(.*?)</select>', body, re.DOTALL
            ):
                fields[name] = re.findall(r'<option value="([^"]*)"', options)[0]
            if integers:
                forms.append((_attr(attrs, "action"), fields, integers))
    return forms


def test_huge_and_negative_integers_in_every_page_form_are_4xx(researcher_page, study) -> None:
    """Integers past any database column (SQLite raises OverflowError on them), or below
    zero, in any integer field of any form: the form again with its errors, or an error
    page; never a 500."""
    forms = page_forms(researcher_page, study["id"])
    checked = {(action, name) for action, _, integers in forms for name in integers}
    assert {
        ("/runs", "study_id"),
        ("/runs", "timesteps"),
        ("/studies", "n_candidates"),
        (f"/studies/{study['id']}/participants", "count"),
    } <= checked
    for action, fields, integers in forms:
        for name in integers:
            for bad in ("99999999999999999999", "-99999999999999999999", "-1"):
                _clean(researcher_page.post(action, data=fields | {name: bad}))


@pytest.mark.parametrize("path", ["/api/studies", "/login", "/api/matches/1/label"])
def test_huge_bodies_are_413(client, path: str) -> None:
    _clean(client.post(path, content=b"x" * (MAX_BODY_BYTES + 1), headers=ADMIN))
    assert client.post(path, content=b"x" * (MAX_BODY_BYTES + 1)).status_code == 413


@pytest.mark.parametrize(
    "header",
    [
        b"Bearer \xff\xfe",
        b"Bearer " + b"a" * 10_000,
        b"Basic Zm9vOmJhcg==",
        b"Bearer",
        b"bearer  x y",
    ],
)
def test_odd_credentials_are_401(client, header: bytes) -> None:
    for path in ("/api/studies", "/api/participants/me"):
        response = client.get(path, headers=[(b"Authorization", header)])
        assert response.status_code == 401, (path, header)


@pytest.mark.parametrize(
    "cookie",
    [
        "acv_participant=\xe9\xff",
        "acv_researcher=" + "x" * 5000,
        "acv_participant=../../etc/passwd",
        "acv_csrf=%00",
    ],
)
def test_odd_cookies_are_refused(client, cookie: str) -> None:
    headers = [(b"Cookie", cookie.encode("latin-1"))]
    assert client.get("/api/participants/me", headers=headers).status_code == 401
    assert client.get("/participate", headers=headers).status_code == 401


@pytest.mark.parametrize(
    ("method", "path", "allow"),
    [
        ("OPTIONS", "/api/studies", "GET, POST"),
        ("PUT", "/api/matches/1/label", "DELETE, POST"),
        ("DELETE", "/api/studies/{sid}/participants", "GET, POST"),
        ("PATCH", "/login", "GET, HEAD, POST"),  # a page: HEAD with its GET
    ],
)
def test_wrong_methods_are_405_with_every_allowed_method(
    client, study, method: str, path: str, allow: str
) -> None:
    response = client.request(method, path.format(sid=study["id"]), headers=ADMIN)
    assert (response.status_code, response.headers["allow"]) == (405, allow)


@pytest.mark.parametrize(
    "body",
    [
        lambda a: {"winner": str(a)},
        lambda a: {"winner": a, "response_ms": False},
        lambda a: {"winner": a, "response_ms": "5"},
        lambda a: {"winner": a + 0.5},
        lambda a: {"winner": float(a)},
        lambda a: {"winner": a, "response_ms": 500.0},
    ],
)
def test_json_numbers_are_not_guessed_from_other_types(client, invite, body) -> None:
    """``"3"``, ``false`` or ``3.0`` where the schema says integer are refused, not coerced
    (lax parsing would have stored these labels): one rule for every integer field."""
    player = invite()
    match = player.next_match()
    response = client.post(
        f"/api/matches/{match['match_id']}/label",
        headers=player.headers,
        json=body(match["a"]["candidate_id"]),
    )
    assert response.status_code == 422 and player.next_match() == match
    whole = {"winner": match["a"]["candidate_id"]}
    assert (
        client.post(
            f"/api/matches/{match['match_id']}/label", headers=player.headers, json=whole
        ).status_code
        == 201
    )


@pytest.mark.parametrize(
    "content", [b"", b"not a checkpoint", b"PK\x03\x04" + b"\x00" * 64, b"\x80\x02garbage"]
)
def test_corrupt_checkpoints_are_refused_with_a_clear_message(
    client, settings, study, content: bytes
) -> None:
    """The backfill job stores why a checkpoint cannot be judged; readers answer with it."""
    run_id = client.post(
        "/api/runs",
        headers=ADMIN,
        json={"study_id": study["id"], "teacher": "good", "algo": "ppo-shaped", "timesteps": 1000},
    ).json()["id"]
    path = checkpoint_path(settings.data_dir / "runs" / str(run_id), 256)
    path.parent.mkdir(parents=True)
    path.write_bytes(content)
    assert client.post(f"/api/runs/{run_id}/cancel", headers=ADMIN).status_code == 202
    sessions = make_sessions(make_engine(settings.sqlalchemy_url))
    with sessions() as session:  # as the executor records a checkpoint it saved
        session.add(RunCheckpoint(run_id=run_id, step=256))
        session.commit()
    assert artefacts.backfill(sessions, runs_root=settings.data_dir / "runs") == 1
    for url in (
        f"/api/runs/{run_id}/agent-tree",
        f"/api/runs/{run_id}/conformance",
        f"/api/runs/{run_id}/trees/agent.svg",
    ):
        response = client.get(url, headers=ADMIN)
        assert response.status_code == 422, (url, response.text)
        assert "step_256.pt is not" in response.json()["detail"]
    curve = client.get(f"/api/runs/{run_id}/conformance-curve", headers=ADMIN)
    assert curve.status_code == 200 and curve.json() == []


@pytest.mark.parametrize("advice", [{"format": "acv.tree/9"}, {"not": "a tree"}, []])
def test_a_corrupt_stored_tree_is_refused_with_a_clear_message(
    client, settings, study, advice
) -> None:
    run_id = client.post(
        "/api/runs",
        headers=ADMIN,
        json={"study_id": study["id"], "teacher": "good", "algo": "ppo-shaped", "timesteps": 1000},
    ).json()["id"]
    engine = make_engine(settings.sqlalchemy_url)
    with make_sessions(engine)() as session:
        session.execute(update(Run).where(Run.id == run_id).values(advice=advice))
        session.commit()
    engine.dispose()
    response = client.get(f"/api/runs/{run_id}/advice-tree", headers=ADMIN)
    assert response.status_code == 422 and response.json()["detail"], response.text


def test_huge_integers_in_every_query_parameter_are_answered(client) -> None:
    """Integers far past any database column (SQLite raises OverflowError on them): a 4xx,
    or an answer where the value is only compared (``after`` in a run's metrics)."""
    schema = client.get("/openapi.json").json()
    asked = 0
    for path, operations in schema["paths"].items():
        for method, operation in operations.items():
            for param in operation.get("parameters", []):
                types = {s.get("type") for s in param["schema"].get("anyOf", [param["schema"]])}
                if param["in"] == "query" and "integer" in types:
                    url = re.sub(r"\{\w+\}", "1", path)
                    for huge in (10**22, -(10**22)):
                        response = client.request(
                            method, url, params={param["name"]: huge}, headers=ADMIN
                        )
                        assert response.status_code < 500, (url, param["name"], huge)
                        asked += 1
    assert asked >= 4


def test_a_page_that_does_not_exist_is_a_page_for_browsers(client) -> None:
    """A participant who mistypes a link sees a page, not the API's JSON; clients and the
    API keep the JSON answer."""
    html = {"Accept": "text/html,application/xhtml+xml"}
    page = client.get("/participate/nope", headers=html)
    assert page.status_code == 404 and page.headers["content-type"].startswith("text/html")
    assert "There is no such page" in page.text and audit(page.text) == []
    for path, accept in (("/participate/nope", "*/*"), ("/api/nope", html["Accept"])):
        answer = client.get(path, headers={"Accept": accept})
        assert answer.status_code == 404 and answer.json() == {"detail": "Not Found"}, path
