"""Browsing the app without a browser: separate cookie jars, CSRF tokens, a researcher login,
and the audit of a page's scripts and styles (the CSP forbids anything inline)."""

from __future__ import annotations

import html as html_lib
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


def logged_in(client: TestClient, address: str = "testclient", **kwargs: Any) -> TestClient:
    """A cookie jar logged in as the researcher (with the tests' admin token); ``kwargs``
    go to :func:`browser`."""
    page = browser(client, address, **kwargs)
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


#: Fields that cannot be what is wrong (an invitation's note), never pointed at the reason.
UNMARKED = {"invite-name"}


def _input(page: str, input_id: str) -> str:
    """The ``<input>`` or ``<select>`` element with ``input_id``."""
    found = re.search(rf'<(?:input|select) id="{input_id}"[^>]*>', page)
    assert found, f"no #{input_id}"
    return found.group(0)


def shown_again(page: str, form: str, typed: dict[str, str], inputs: dict[str, str]) -> None:
    """A refused form (``app.http.forms``) in ``page``: its reason beside it, each of
    ``inputs`` (element id -> field) holding what was ``typed`` and pointing at the reason."""
    reason = re.search(rf'<p class="field-error" id="{form}-error" role="alert">([^<]+)</p>', page)
    assert reason and reason.group(1).startswith("Not saved: "), form
    for input_id, field in inputs.items():
        element = _input(page, input_id)
        assert f'value="{html_lib.escape(typed[field])}"' in element, element
        marked = f'aria-describedby="{form}-error"' in element
        assert marked == (input_id not in UNMARKED), element
