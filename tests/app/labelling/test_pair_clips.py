"""Clips on the pairs after the bracket (issue 41 §3), through the pages on both databases: in a
study whose clips are rendered, the disagreement pairs and the consistency check show each
side's clip with a Pause/Play toggle (stills without JavaScript), and the answer stores what
was shown (``stimulus``); the labels export carries it on the disagreement rows. Anything but
``still`` or ``clip``, and ``clip`` where the pair has no clips, is refused with the reason and
stores nothing; a form without ``stimulus`` answered stills."""

from __future__ import annotations

import csv
import io
import json
import re
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import text

from app.db import make_engine
from app.settings import Settings
from tests.support.crowd import configure
from tests.support.runs import TINY, create_run, run_app, wait_run
from tests.support.studies import Player, new_study
from tests.support.wait import wait_for
from tests.support.web import ADMIN, browser, csrf_token

pytestmark = [pytest.mark.training, pytest.mark.postgres_only]
# postgres_only: rendering clips is the subject, not storage.

#: Rendering 4 clips of 2 s: seconds, more on a loaded 2-core machine.
RENDER_S = 240
BODY: dict[str, Any] = {"n_candidates": 4, "seed": 7, "disagreement_pairs": 3}
PAIR = "disagreement"
CLIP = re.compile(r'data-clip="/api/studies/\d+/candidates/(\d+)/clip"')


@pytest.fixture(scope="module")
def client(settings: Settings) -> Iterator[TestClient]:
    with run_app(settings) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def baseline(client: TestClient) -> int:
    """A finished tiny no-advice ppo run on Hopper (disagreement pairs need one)."""
    host = new_study(client, n_candidates=4)
    run = create_run(client, study_id=host["id"], algo="ppo", timesteps=256, **TINY)
    assert wait_run(client, run)["status"] == "succeeded"
    return run


def _study(client: TestClient, **overrides: Any) -> dict[str, Any]:
    """A 4-candidate study asking 3 disagreement pairs and the consistency check."""
    ready = new_study(client, **BODY, **overrides)
    assert ready["status"] == "ready" and ready["disagreement_pairs"] == 3, ready
    configure(client, ready["id"], consistency_check=True)
    return ready


@pytest.fixture(scope="module")
def clip_study(client: TestClient, baseline: int) -> dict[str, Any]:
    ready = _study(client, clips=True)
    done = wait_for(
        lambda: client.get(f"/api/studies/{ready['id']}", headers=ADMIN).json(),
        lambda body: body["clips_ready"] or body["error"],
        what="the study's clips",
        timeout_s=RENDER_S,
        every_s=0.2,
    )
    assert done["clips_ready"] and done["error"] is None, done
    return done


@pytest.fixture(scope="module")
def still_study(client: TestClient, baseline: int) -> dict[str, Any]:
    return _study(client)


def _finished(client: TestClient, study: dict[str, Any]) -> tuple[Player, TestClient]:
    """A participant who finished the bracket against the baseline, and their browser."""
    body = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    player = Player(client, body["id"], body["token"], body["invite_url"])
    returns = {
        c["id"]: c["baseline_return"]
        for c in client.get(f"/api/studies/{study['id']}/candidates", headers=ADMIN).json()
    }
    player.play(
        lambda m: min(m["a"]["candidate_id"], m["b"]["candidate_id"], key=returns.__getitem__)
    )
    page = browser(client)
    assert page.get(f"/p/{player.token}").headers["location"] == "/participate/thanks"
    return player, page


def _pairs(player: Player) -> list[dict[str, Any]]:
    return player.client.get("/api/participants/me/pairs", headers=player.headers).json()


def _post(page: TestClient, path: str, **fields: str) -> Any:
    return page.post(path, data={"csrf_token": csrf_token(page, path), **fields})


def _stored(settings: Settings, table: str, pid: int) -> list[tuple[Any, str]]:
    """``(winner, stimulus)`` of the participant's rows of ``table``, in order."""
    engine = make_engine(settings.sqlalchemy_url)
    order = "position" if table == "disagreement_pairs" else "participant_id"
    try:
        with engine.connect() as conn:
            rows = conn.execute(
                text(
                    f"SELECT winner, stimulus FROM {table} "  # noqa: S608  # our own names
                    f"WHERE participant_id = :p ORDER BY {order}"
                ),
                {"p": pid},
            )
            return [(w, s) for w, s in rows]
    finally:
        engine.dispose()


def _exported(client: TestClient, study: dict[str, Any], pid: int) -> list[str]:
    """The stimulus of the participant's disagreement rows in the labels export, the same in
    its JSONL and its CSV."""
    base = f"/api/studies/{study['id']}/export/labels"
    lines = client.get(f"{base}.jsonl", headers=ADMIN).text.splitlines()
    rows = [json.loads(line) for line in lines]
    table = csv.DictReader(io.StringIO(client.get(f"{base}.csv", headers=ADMIN).text))
    as_csv = [r["stimulus"] for r in table if (r["participant_id"], r["kind"]) == (str(pid), PAIR)]
    found = [r["stimulus"] for r in rows if (r["participant_id"], r["kind"]) == (pid, PAIR)]
    assert as_csv == found
    return found


def test_the_pairs_of_a_clips_study_show_clips_and_store_what_was_shown(
    client: TestClient, settings: Settings, clip_study: dict[str, Any]
) -> None:
    player, page = _finished(client, clip_study)
    pairs = _pairs(player)
    assert len(pairs) >= 2, pairs  # the participant went against the baseline
    shown = page.get("/participate/pairs").text
    assert CLIP.findall(shown) == [str(pairs[0]["left"]), str(pairs[0]["right"])]
    assert 'id="pair-motion-left"' in shown and 'id="pair-motion-right"' in shown
    assert "/static/js/pair_motion.js" in shown and "/static/js/clip_motion.js" in shown
    assert 'name="stimulus" id="pair-stimulus" value="still"' in shown  # until a clip plays
    first = str(pairs[0]["left"])
    for bad in ("video", "", "CLIP", "clip "):
        refused = _post(page, "/participate/pairs", position="0", winner=first, stimulus=bad)
        assert refused.status_code == 422 and "stimulus must be" in refused.text, bad
    assert _stored(settings, "disagreement_pairs", player.id)[0] == (None, "still")  # nothing
    answered = _post(page, "/participate/pairs", position="0", winner=first, stimulus="clip")
    assert answered.status_code == 303 and answered.headers["location"] == "/participate/pairs"
    # A form without the field (sent before this page had it) answered stills.
    for p in pairs[1:]:
        sent = _post(page, "/participate/pairs", position=str(p["position"]), winner=str(p["left"]))
        assert sent.status_code == 303, sent.text
    expected = ["clip"] + ["still"] * (len(pairs) - 1)
    stored = _stored(settings, "disagreement_pairs", player.id)
    assert [s for _, s in stored] == expected and None not in [w for w, _ in stored]
    assert _exported(client, clip_study, player.id) == expected

    assert page.get("/participate/pairs").headers["location"] == "/participate/thanks"
    assert page.get("/participate/thanks").headers["location"] == "/participate/check"
    check = page.get("/participate/check").text
    assert len(CLIP.findall(check)) == 2 and 'id="check-motion-left"' in check
    left = re.search(r'value="(\d+)" id="check-left"', check)
    assert left is not None
    bad = _post(page, "/participate/check", winner=left.group(1), stimulus="gif")
    assert bad.status_code == 422 and "stimulus must be" in bad.text
    assert _stored(settings, "consistency_checks", player.id) == [(None, "still")]
    done = _post(page, "/participate/check", winner=left.group(1), stimulus="clip")
    assert done.status_code == 303 and done.headers["location"] == "/participate/thanks"
    assert _stored(settings, "consistency_checks", player.id) == [(int(left.group(1)), "clip")]


def test_clip_is_refused_where_the_pair_has_no_clips(
    client: TestClient, settings: Settings, still_study: dict[str, Any]
) -> None:
    player, page = _finished(client, still_study)
    pairs = _pairs(player)
    assert pairs, "the participant went against the baseline: pairs disagree"
    shown = page.get("/participate/pairs").text
    assert "data-clip" not in shown and "pair_motion.js" not in shown and "pair-motion" not in shown
    assert 'name="stimulus" id="pair-stimulus" value="still"' in shown
    first = str(pairs[0]["left"])
    refused = _post(page, "/participate/pairs", position="0", winner=first, stimulus="clip")
    assert refused.status_code == 422 and "no clips to show" in refused.text
    assert _pairs(player)[0]["winner"] is None  # nothing stored
    for p in pairs:
        winner = str(p["left"])
        answered = _post(
            page, "/participate/pairs", position=str(p["position"]), winner=winner, stimulus="still"
        )
        assert answered.status_code == 303, answered.text
    assert [s for _, s in _stored(settings, "disagreement_pairs", player.id)] == ["still"] * len(
        pairs
    )
    assert _exported(client, still_study, player.id) == ["still"] * len(pairs)

    check = page.get("/participate/check").text
    assert "data-clip" not in check and 'id="check-stimulus" value="still"' in check
    left = re.search(r'value="(\d+)" id="check-left"', check)
    assert left is not None
    refused = _post(page, "/participate/check", winner=left.group(1), stimulus="clip")
    assert refused.status_code == 422 and "no clips to show" in refused.text
    assert _stored(settings, "consistency_checks", player.id) == [(None, "still")]
    done = _post(page, "/participate/check", winner=left.group(1), stimulus="still")
    assert done.status_code == 303 and done.headers["location"] == "/participate/thanks"
    assert _stored(settings, "consistency_checks", player.id) == [(int(left.group(1)), "still")]
