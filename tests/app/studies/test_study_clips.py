"""Clips in ordinary studies (issue 41 §3), through the API with real rendering, on both
databases: a study with clips is ready with stills first, then each candidate gets its clip
with the policy and seed that rolled it; the participant's next match carries the clips once
both are rendered, a label records what was shown (``stimulus``) and every export carries it;
``clip`` where a pair has no clips, and anything but ``still`` or ``clip``, are refused;
``clips`` is a strict boolean; ``acv study create --clips`` renders them too."""

from __future__ import annotations

import csv
import io
import json
import re
from typing import Any

import pyarrow.parquet as pq
import pytest
from fastapi.testclient import TestClient

from engine.evaluation.stimuli import STIMULUS_SEED0
from tests.support.cli import acv
from tests.support.studies import new_study
from tests.support.wait import wait_for
from tests.support.web import ADMIN, logged_in

# postgres_only: rendering clips is the subject, not storage.
pytestmark = pytest.mark.postgres_only

#: Rendering 4 clips of 2 s: seconds, more on a loaded 2-core machine.
RENDER_S = 240


def clips_ready(client: TestClient, study_id: int) -> dict[str, Any]:
    return wait_for(
        lambda: client.get(f"/api/studies/{study_id}", headers=ADMIN).json(),
        lambda body: body["clips_ready"] or body["error"],
        what=f"the clips of study {study_id}",
        timeout_s=RENDER_S,
        every_s=0.2,
    )


@pytest.fixture(scope="module")
def clip_study(client: TestClient) -> dict[str, Any]:
    ready = new_study(client, n_candidates=4, seed=5, clips=True)
    assert ready["status"] == "ready" and ready["clips"], ready
    done = clips_ready(client, ready["id"])
    assert done["clips_ready"] and done["error"] is None, done
    return done


def test_a_clips_study_is_ready_with_stills_then_gets_its_clips(
    client: TestClient, clip_study: dict[str, Any]
) -> None:
    sid = clip_study["id"]
    cands = client.get(f"/api/studies/{sid}/candidates", headers=ADMIN).json()
    assert len(cands) == 4
    for c in cands:
        assert c["clip_url"] == f"/api/studies/{sid}/candidates/{c['id']}/clip"
        assert (c["clip_policy"], c["clip_seed"]) == ("random actions", STIMULUS_SEED0)
    served = client.get(cands[0]["clip_url"], headers=ADMIN)
    assert served.status_code == 200 and served.headers["content-type"] == "image/webp"
    assert served.content[:4] == b"RIFF" and b"ANIM" in served.content[:64]
    # Served as the images are: not to a stranger.
    assert client.get(cands[0]["clip_url"]).status_code in (401, 404)
    page = logged_in(client).get(f"/studies/{sid}")
    assert 'id="clips-state">clips ready' in page.text


def test_a_label_records_the_clip_it_showed_and_every_export_carries_it(
    client: TestClient, clip_study: dict[str, Any], invite
) -> None:
    sid = clip_study["id"]
    player = invite(sid)
    match = player.next_match()
    assert match is not None and match["gold"] is None
    assert match["a"]["clip_url"] and match["b"]["clip_url"]
    answer = player.label(match["match_id"], match["a"]["candidate_id"], stimulus="clip")
    assert answer.status_code == 201, answer.text
    assert answer.json()["next"]["a"]["clip_url"]
    nxt = answer.json()["next"]
    assert player.label(nxt["match_id"], nxt["b"]["candidate_id"]).status_code == 201
    base = f"/api/studies/{sid}/export/labels"
    rows = [
        json.loads(line) for line in client.get(base + ".jsonl", headers=ADMIN).text.splitlines()
    ]
    mine = [r for r in rows if r["participant_id"] == player.id]
    assert [r["stimulus"] for r in mine] == ["clip", "still"]
    table = list(csv.DictReader(io.StringIO(client.get(base + ".csv", headers=ADMIN).text)))
    assert [r["stimulus"] for r in table if r["participant_id"] == str(player.id)] == [
        "clip",
        "still",
    ]
    parquet = pq.read_table(io.BytesIO(client.get(base + ".parquet", headers=ADMIN).content))
    assert parquet.column("stimulus").to_pylist()[-2:] == ["clip", "still"]
    plain = client.get(f"/api/studies/{sid}/labels.csv", headers=ADMIN).text
    assert list(csv.DictReader(io.StringIO(plain)))[-2]["stimulus"] == "clip"


def test_clip_where_the_pair_has_none_and_other_stimuli_are_refused(
    client: TestClient, study: dict[str, Any], invite
) -> None:
    player = invite(study["id"])  # a study without clips
    match = player.next_match()
    assert match is not None and match["a"]["clip_url"] is None
    winner = match["a"]["candidate_id"]
    refused = player.label(match["match_id"], winner, stimulus="clip")
    assert refused.status_code == 422 and "no clips" in refused.json()["detail"]
    for bad in ("video", "", 1, True, None):
        wrong = player.label(match["match_id"], winner, stimulus=bad)
        assert wrong.status_code == 422, (bad, wrong.text)
    assert player.next_match()["match_id"] == match["match_id"]  # nothing was stored
    assert player.label(match["match_id"], winner, stimulus="still").status_code == 201


@pytest.mark.parametrize("clips", ["true", 1, 0, None, "yes"])
def test_clips_is_a_strict_boolean(client: TestClient, clips: object) -> None:
    body = {"name": "x", "env_id": "Hopper-v5", "n_candidates": 4, "clips": clips}
    assert client.post("/api/studies", json=body, headers=ADMIN).status_code == 422


def test_clips_are_off_by_default(client: TestClient, study: dict[str, Any]) -> None:
    assert (study["clips"], study["clips_ready"]) == (False, False)
    assert 'id="clips-state"' not in logged_in(client).get(f"/studies/{study['id']}").text


def test_the_form_offers_clips_with_the_warning(client: TestClient) -> None:
    form = logged_in(client).get("/studies/new").text
    assert 'name="clips"' in form and "rewards the posture alone" in form


def test_acv_study_create_clips(monkeypatch, backend_url) -> None:
    data_dir, url = backend_url
    monkeypatch.setenv("ACV_DATA_DIR", str(data_dir))
    monkeypatch.setenv("DATABASE_URL", url)
    args = ["--env", "Hopper-v5", "--candidates", "3", "--seed", "4"]
    created = acv("study", "create", "--name", "cli clips", *args, "--clips")
    assert created.exit_code == 0, created.output
    assert re.search(r"study \d+ ready: 3 Hopper-v5 candidates\nclips ready", created.output)
    assert "--clips" in acv("study", "create", "--help").output
