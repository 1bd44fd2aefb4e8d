"""Browsing the app without a browser: separate cookie jars, CSRF tokens, a researcher login,
and the audit of a page's scripts and styles (the CSP forbids anything inline)."""

from __future__ import annotations

import re
from html.parser import HTMLParser
from typing import Any

from fastapi.testclient import TestClient

#: The researcher's token in the in-process app tests (at least 32 characters).
ADMIN_TOKEN = "test-admin-token-0123456789abcdefghij"
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
CSRF_RE = re.compile(r'name="csrf_token" value="([^"]+)"')


def browser(client: TestClient, address: str = "testclient", **kwargs: Any) -> TestClient:
    """A separate cookie jar on the same running app (the fixture's client holds none), from
    client ``address``; redirects are not followed."""
    return TestClient(client.app, follow_redirects=False, client=(address, 40000), **kwargs)


def csrf_token(page: TestClient, path: str = "/login") -> str:
    """The CSRF token of the form on ``path`` (this also sets the CSRF cookie)."""
    match = CSRF_RE.search(page.get(path).text)
    assert match, f"no CSRF field on {path}"
    return match.group(1)


def logged_in(client: TestClient, address: str = "testclient") -> TestClient:
    """A cookie jar logged in as the researcher (with the tests' admin token)."""
    page = browser(client, address)
    response = page.post(
        "/login", data={"csrf_token": csrf_token(page), "token": ADMIN_TOKEN, "next": "/studies"}
    )
    assert response.status_code == 303, response.text
    return page


class ScriptAudit(HTMLParser):
    """Collects inline scripts, inline event handlers and style attributes of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.problems: list[str] = []
        self._in_script = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        names = [name for name, _ in attrs]
        self._in_script = tag == "script" and "src" not in names
        self.problems += [f"<{tag} {n}=...>" for n in names if n.startswith("on") or n == "style"]
        if any(n == "href" and (v or "").lower().startswith("javascript:") for n, v in attrs):
            self.problems.append(f"<{tag} href=javascript:...>")

    def handle_data(self, data: str) -> None:
        if self._in_script and data.strip():
            self.problems.append("inline <script>")

    def handle_endtag(self, tag: str) -> None:
        self._in_script = False


def audit(html: str) -> list[str]:
    """What in ``html`` the CSP would block: inline scripts, handlers, style attributes."""
    parser = ScriptAudit()
    parser.feed(html)
    return parser.problems
