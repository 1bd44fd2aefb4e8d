"""Browser-facing defences: cookie flags, CSRF on every form post and on cookie-authenticated
JSON calls, security headers on every kind of response (the self-hosted API docs included),
researcher sessions that expire on the server, and rate-limited logins and bearer tokens.

Runs on PostgreSQL (the ``client`` fixture); each test uses its own cookie jar.
"""

from __future__ import annotations

import base64
import hashlib
import re
import time
from http.cookies import SimpleCookie

import pytest
from fastapi.routing import iter_route_contexts
from fastapi.testclient import TestClient

from app.core import auth
from app.http.deps import AJAX_HEADER
from app.http.ratelimit import FAILED_LOGINS_PER_MINUTE
from app.middleware import MAX_BODY_BYTES
from tests.support.studies import Player
from tests.support.web import ADMIN, ADMIN_TOKEN, browser, csrf_token, logged_in

# postgres_only: pages are the subject, not storage.
pytestmark = pytest.mark.postgres_only

AJAX = dict([AJAX_HEADER])


def cookie_attributes(response, name: str) -> dict[str, str | bool]:
    """The attributes of the ``Set-Cookie`` header that sets ``name``."""
    for header in response.headers.get_list("set-cookie"):
        jar = SimpleCookie()
        jar.load(header)
        if name in jar:
            morsel = jar[name]
            return {k: morsel[k] for k in ("httponly", "samesite", "secure") if morsel[k]}
    raise AssertionError(f"{name} is not set: {response.headers.get_list('set-cookie')}")


@pytest.mark.parametrize("base_url", ["http://testserver", "https://testserver"])
def test_every_cookie_is_httponly_and_samesite(client, invite, base_url: str) -> None:
    secure = {"secure": True} if base_url.startswith("https") else {}
    page = browser(client, base_url=base_url)
    assert (
        cookie_attributes(page.get("/login"), "acv_csrf")
        == {"httponly": True, "samesite": "strict"} | secure
    )
    login = page.post("/login", data={"csrf_token": csrf_token(page), "token": ADMIN_TOKEN})
    assert (
        cookie_attributes(login, "acv_researcher") == {"httponly": True, "samesite": "lax"} | secure
    )
    link = browser(client, base_url=base_url).get(f"/p/{invite().token}")
    assert (
        cookie_attributes(link, "acv_participant") == {"httponly": True, "samesite": "lax"} | secure
    )


def test_cookie_label_needs_the_ajax_header(client, invite) -> None:
    """A cross-site form can send the participant's cookie but not a custom header."""
    player: Player = invite()
    page = browser(client)
    page.get(f"/p/{player.token}")  # the invite link sets the participant cookie
    match = player.next_match()
    url, body = f"/api/matches/{match['match_id']}/label", {"winner": match["a"]["candidate_id"]}
    forged = page.post(url, json=body)
    assert forged.status_code == 403 and AJAX_HEADER[0] in forged.json()["detail"]
    assert player.next_match() == match  # nothing stored
    assert page.delete(url).status_code == 403
    assert page.post("/api/participants/me/undo").status_code == 403
    assert page.get("/api/participants/me/next-match").status_code == 200  # reads are fine
    assert page.post(url, json=body, headers=AJAX).status_code == 201
    assert page.post("/api/participants/me/undo", headers=AJAX).status_code == 200


def test_cookie_researcher_writes_need_the_ajax_header(client, study) -> None:
    page = logged_in(client)
    url = f"/api/studies/{study['id']}/participants"
    before = len(client.get(url, headers=ADMIN).json())
    assert page.post(url, json={}).status_code == 403
    assert page.post("/api/studies", json={"name": "x", "n_candidates": 2}).status_code == 403
    assert len(client.get(url, headers=ADMIN).json()) == before
    assert page.get(url).status_code == 200
    assert page.post(url, json={}, headers=AJAX).status_code == 201
    assert browser(client).post(url, json={}, headers=ADMIN).status_code == 201  # bearer


def _form_routes(client: TestClient) -> list[str]:
    return sorted(
        {
            route.path
            for route in iter_route_contexts(client.app.routes)
            if "POST" in (route.methods or ()) and not route.path.startswith("/api/")
        }
    )


def test_every_form_post_needs_a_csrf_token(client, study) -> None:
    """Every state-changing page route refuses a post without (or with a forged) token, even
    from a logged-in researcher."""
    routes = _form_routes(client)
    assert {"/login", "/logout", "/studies"} <= set(routes)
    page = logged_in(client)
    ids = {"study_id": study["id"], "run_id": 2**31 - 1, "survey_id": 2**31 - 1, "slug": "no-link"}
    ids["webhook_id"] = ids["item_id"] = ids["participant_id"] = 2**31 - 1
    ids["evaluation_id"] = ids["experiment_id"] = 2**31 - 1
    for path in routes:
        url = re.sub(r"\{(\w+)\}", lambda m: str(ids[m.group(1)]), path)
        for fields in ({}, {"csrf_token": "forged"}):
            response = page.post(url, data={"count": "1", "name": "x", **fields})
            assert response.status_code == 403, (url, fields, response.text[:200])
    assert page.get("/studies").status_code == 200  # still logged in: logout was refused


def _has_full_page_policy(response) -> None:
    csp = response.headers["content-security-policy"]
    directives = dict(d.strip().split(" ", 1) for d in csp.split(";"))
    assert directives["script-src"] == "'self'" and "unsafe" not in csp
    assert directives["frame-ancestors"] == "'none'"
    assert response.headers["x-content-type-options"] == "nosniff"


@pytest.mark.parametrize(
    "path", ["/login", "/studies", "/studies/new", "/studies/{id}", "/studies/999999", "/studies/0"]
)
def test_pages_send_a_strict_policy(client, study, path: str) -> None:
    _has_full_page_policy(logged_in(client).get(path.format(id=study["id"])))


@pytest.mark.parametrize("path", ["/participate", "/participate/label"])
def test_participant_pages_send_a_strict_policy(client, invite, path: str) -> None:
    page = browser(client)
    page.get(f"/p/{invite().token}")
    _has_full_page_policy(page.get(path))


@pytest.mark.parametrize(
    "path",
    [
        "/api/studies",
        "/api/studies/{id}",
        "/api/studies/{id}/candidates/0/image",
        "/static/js/api.js",
        "/static/css/acv.css",
        "/healthz",
        "/api/nowhere",
        "/openapi.json",
        "/docs",
    ],
)
def test_every_other_response_forbids_sniffing_and_framing(client, study, path: str) -> None:
    response = client.get(path.format(id=study["id"]), headers=ADMIN)
    assert response.status_code in (200, 404), response.text
    assert response.headers["x-content-type-options"] == "nosniff"
    assert response.headers["x-frame-options"] == "DENY"
    assert "frame-ancestors 'none'" in response.headers["content-security-policy"]


def test_oversized_bodies_are_refused_before_reading(client) -> None:
    big = b"{" + b" " * MAX_BODY_BYTES + b"}"
    declared = client.post("/api/studies", content=big, headers=ADMIN)
    streamed = client.post(
        "/api/studies", content=iter([big[:1000], big[1000:]]), headers=ADMIN
    )  # chunked: no Content-Length
    for response in (declared, streamed):
        assert response.status_code == 413 and "detail" in response.json()
        assert response.headers["x-content-type-options"] == "nosniff"


def test_failed_logins_are_rate_limited_per_address(client) -> None:
    """After the limit, even the right token is refused (without being compared) until the
    window frees; other addresses are unaffected."""
    page = browser(client, "203.0.113.7")
    token = csrf_token(page)
    for _ in range(FAILED_LOGINS_PER_MINUTE):
        assert page.post("/login", data={"csrf_token": token, "token": "guess"}).status_code == 401
    blocked = page.post("/login", data={"csrf_token": token, "token": ADMIN_TOKEN})
    assert blocked.status_code == 429 and 1 <= int(blocked.headers["retry-after"]) <= 60
    assert "acv_researcher" not in blocked.headers.get("set-cookie", "")
    assert logged_in(client, "203.0.113.8").get("/studies").status_code == 200


def test_successful_logins_are_not_counted(client) -> None:
    for _ in range(FAILED_LOGINS_PER_MINUTE + 2):
        logged_in(client, "203.0.113.9")


def test_failed_bearer_tokens_are_rate_limited_per_address(client, invite) -> None:
    """Wrong bearer tokens count as failed logins of the address: past the limit even the
    admin token gets 429 (without being compared), on researcher and shared routes, and the
    login form is closed too. Invite tokens are credentials, not guesses: never counted,
    never refused. Other addresses are unaffected."""
    api, player = browser(client, "203.0.113.20"), invite()
    player.play()
    tree, guess = f"/api/participants/{player.id}/tree", {"Authorization": "Bearer guess"}
    for _ in range(FAILED_LOGINS_PER_MINUTE + 2):  # another role's token on a researcher route
        assert api.get("/api/studies", headers=player.headers).status_code == 401
    assert api.get("/api/studies", headers=ADMIN).status_code == 200
    for i in range(FAILED_LOGINS_PER_MINUTE):
        assert api.get(tree if i % 2 else "/api/studies", headers=guess).status_code == 401
    for path in ("/api/studies", tree):
        blocked = api.get(path, headers=ADMIN)
        assert blocked.status_code == 429 and "detail" in blocked.json(), path
        assert 1 <= int(blocked.headers["retry-after"]) <= 60
    assert api.get(tree, headers=player.headers).status_code == 200
    assert (
        api.post("/login", data={"csrf_token": csrf_token(api), "token": ADMIN_TOKEN}).status_code
        == 429
    )
    assert browser(client, "203.0.113.21").get("/api/studies", headers=ADMIN).status_code == 200


def test_researcher_sessions_expire_on_the_server(client) -> None:
    """The cookie holds a signed login time; the server refuses it after the session length
    (whatever the browser keeps), and a cookie whose time was moved is refused at once."""
    max_age = client.app.state.runtime.settings.session_max_age_s
    assert max_age == 12 * 3600
    page = browser(client)
    login = page.post("/login", data={"csrf_token": csrf_token(page), "token": ADMIN_TOKEN})
    assert [
        h
        for h in login.headers.get_list("set-cookie")
        if h.startswith(auth.RESEARCHER_COOKIE) and f"Max-Age={max_age};" in h
    ]
    fresh = auth.researcher_cookie_value(admin_token=ADMIN_TOKEN)
    stale = auth.researcher_cookie_value(
        admin_token=ADMIN_TOKEN, issued_at=time.time() - max_age - 5
    )
    issued, rest = stale.split(".", 1)
    moved = f"{int(issued) + 600}.{rest}"
    for cookie, valid in ((fresh, True), (stale, False), (moved, False)):
        headers = {"Cookie": f"{auth.RESEARCHER_COOKIE}={cookie}"}
        page = browser(client).get("/studies", headers=headers)
        assert (page.status_code == 200) is valid, (cookie, page.status_code)
        assert page.status_code == 200 or page.headers["location"].startswith("/login")
        api = browser(client).get("/api/studies", headers=headers)
        assert api.status_code == (200 if valid else 401)


def test_api_docs_run_only_this_origins_code(client) -> None:
    """Swagger UI comes from static/vendor; its one inline script is allowed by its hash, and
    nothing else inline or from elsewhere; ReDoc is not served."""
    response = client.get("/docs")
    assert response.status_code == 200
    directives = dict(
        d.strip().split(" ", 1) for d in response.headers["content-security-policy"].split(";")
    )
    inline = re.findall(r"<script>(.*?)</script>", response.text, re.DOTALL)
    assert len(inline) == 1
    digest = base64.b64encode(hashlib.sha256(inline[0].encode()).digest()).decode()
    assert directives["script-src"] == f"'self' 'sha256-{digest}'"
    assert directives["default-src"] == "'none'" and directives["frame-ancestors"] == "'none'"
    assert "unsafe" not in response.headers["content-security-policy"]
    assets = re.findall(r'(?:src|href)="([^"]+)"', response.text)
    assert {"/static/vendor/swagger-ui-bundle.js", "/static/vendor/swagger-ui.css"} <= set(assets)
    for asset in assets:
        assert asset.startswith("/static/") and client.get(asset).status_code == 200, asset
    assert "Apache License" in client.get("/static/vendor/swagger-ui.LICENSE").text
    assert client.get("/redoc").status_code == 404
