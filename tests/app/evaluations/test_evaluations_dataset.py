"""An evaluation's answers for reuse (issue 41 §2: "exported with the labels ..., with the
stimulus kind"), on both databases: ``answers.jsonl`` and ``answers.parquet`` hold
``answers.csv``'s columns, one row per kept answer, each with what was shown (``stimulus``,
``reminder``); a withdrawn evaluator's answers are left out; researcher only.

The evaluation is a bare one (its rows written directly, nothing rendered), answered through
the evaluators' API.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterator
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from datasets import load_dataset
from fastapi.testclient import TestClient

from app.evaluations.results import EXPORT_COLUMNS
from app.models import Evaluation
from tests.support.evaluations import bare_evaluation
from tests.support.hf import PSEUDONYM, card, export, unzipped
from tests.support.runs import TINY, create_run, run_app
from tests.support.studies import Player, new_study
from tests.support.web import ADMIN, csrf_token, logged_in


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def run_study(client: TestClient) -> dict[str, Any]:
    """The study of the bare evaluations' run."""
    return new_study(client, n_candidates=3, seed=6)


@pytest.fixture(scope="module")
def run_id(client: TestClient, run_study: dict[str, Any]) -> int:
    """A run (never trained: the worker is off) for the bare evaluations' slots."""
    return create_run(
        client, study_id=run_study["id"], teacher="good", algo="bipars-em", timesteps=256, **TINY
    )


def _bearers(
    client: TestClient, evaluation_id: int, count: int
) -> list[tuple[int, dict[str, str]]]:
    """``count`` new evaluators: each one's id and bearer header."""
    made = client.post(
        f"/api/evaluations/{evaluation_id}/evaluators", json={"count": count}, headers=ADMIN
    )
    assert made.status_code == 201, made.text
    return [
        (p["id"], {"Authorization": f"Bearer {p['invite_url'].rsplit('/', 1)[1]}"})
        for p in made.json()
    ]


def _player(client: TestClient, study_id: int) -> Player:
    """A new participant of ``study_id`` who decided their whole bracket (the ``a`` sides)."""
    made = client.post(f"/api/studies/{study_id}/participants", headers=ADMIN)
    assert made.status_code == 201, made.text
    body = made.json()
    player = Player(client, body["id"], body["token"], body["invite_url"])
    assert player.play() >= 1
    return player


def _advisor_evaluation(client: TestClient, run_id: int, advisor_id: int) -> int:
    """A bare clip evaluation made an advisor's, with the bracket reminder on."""
    evaluation_id = bare_evaluation(client, run_id=run_id, stimulus="clip")
    with client.app.state.runtime.sessions() as session, session.begin():
        evaluation = session.get(Evaluation, evaluation_id)
        assert evaluation is not None
        evaluation.evaluator_kind, evaluation.advisor_id = "advisor", advisor_id
        evaluation.show_bracket = True
    return evaluation_id


def _answer(client: TestClient, who: dict[str, str], choice: str, stimulus: str) -> None:
    key = client.get("/api/evaluators/me/pairs/next", headers=who).json()["key"]
    body = {"choice": choice, "stimulus": stimulus}
    response = client.post(f"/api/evaluators/me/pairs/{key}", json=body, headers=who)
    assert response.status_code == 200, response.text


@pytest.fixture(scope="module")
def answered(client: TestClient, run_id: int) -> dict[str, Any]:
    """A bare evaluation (2 pairs each): the keeper answers both pairs, one as a clip and one
    as a still; the leaver answers one and withdraws."""
    evaluation_id = bare_evaluation(client, run_id=run_id, stimulus="clip")
    (keeper_id, keeper), (_, leaver) = _bearers(client, evaluation_id, 2)
    _answer(client, keeper, "left", "clip")
    _answer(client, keeper, "tie", "still")
    _answer(client, leaver, "right", "clip")
    left = client.post("/api/evaluators/me/withdraw", json={"withdraw": True}, headers=leaver)
    assert left.status_code == 200, left.text
    return {"id": evaluation_id, "keeper": keeper_id}


def _get(client: TestClient, evaluation_id: int, fmt: str) -> Any:
    response = client.get(f"/api/evaluations/{evaluation_id}/answers.{fmt}", headers=ADMIN)
    assert response.status_code == 200, response.text
    disposition = response.headers["content-disposition"]
    assert f'filename="evaluation-{evaluation_id}-answers.{fmt}"' in disposition
    return response


def test_jsonl_has_the_csv_columns_the_stimulus_kind_and_only_kept_answers(
    client, answered
) -> None:
    response = _get(client, answered["id"], "jsonl")
    assert response.headers["content-type"].startswith("application/x-ndjson")
    rows = [json.loads(line) for line in response.text.splitlines()]
    assert [list(r) for r in rows] == [list(EXPORT_COLUMNS)] * 2
    assert {r["evaluator_id"] for r in rows} == {answered["keeper"]}  # the leaver's: left out
    assert [r["stimulus"] for r in rows] == ["clip", "still"]
    assert [r["reminder"] for r in rows] == [False, False] and [r["tie"] for r in rows] == [
        False,
        True,
    ]
    assert [r["position"] for r in rows] == [0, 1]
    assert all(r["answered_at"].endswith("+00:00") for r in rows)
    table = csv.DictReader(io.StringIO(_get(client, answered["id"], "csv").text))
    assert table.fieldnames == list(EXPORT_COLUMNS)
    in_csv = list(table)
    assert [(r["slot_a"], r["slot_b"], r["stimulus"]) for r in in_csv] == [
        (str(r["slot_a"]), str(r["slot_b"]), r["stimulus"]) for r in rows
    ]


def test_parquet_is_typed_and_holds_the_same_rows(client, answered) -> None:
    response = _get(client, answered["id"], "parquet")
    assert response.headers["content-type"].startswith("application/vnd.apache.parquet")
    table = pq.read_table(io.BytesIO(response.content))
    assert table.column_names == list(EXPORT_COLUMNS) and table.num_rows == 2
    assert table.schema.field("stimulus").type == pa.string()
    assert table.schema.field("tie").type == pa.bool_()
    assert table.schema.field("answered_at").type == pa.timestamp("us", tz="UTC")
    rows = table.to_pylist()
    jsonl = [json.loads(line) for line in _get(client, answered["id"], "jsonl").text.splitlines()]
    for row, same in zip(rows, jsonl, strict=True):
        assert row["answered_at"].isoformat() == same["answered_at"]
        assert {k: v for k, v in row.items() if k != "answered_at"} == {
            k: v for k, v in same.items() if k != "answered_at"
        }


def test_an_unanswered_evaluation_exports_no_rows_with_the_same_columns(client, run_id) -> None:
    evaluation_id = bare_evaluation(client, run_id=run_id)
    assert _get(client, evaluation_id, "jsonl").text == ""
    table = pq.read_table(io.BytesIO(_get(client, evaluation_id, "parquet").content))
    assert table.column_names == list(EXPORT_COLUMNS) and table.num_rows == 0


def test_the_exports_are_the_researchers_and_name_a_real_evaluation(client, answered) -> None:
    for fmt in ("jsonl", "parquet"):
        path = f"/api/evaluations/{answered['id']}/answers.{fmt}"
        assert client.get(path).status_code == 401
        assert (
            client.get(f"/api/evaluations/999999/answers.{fmt}", headers=ADMIN).status_code == 404
        )
        assert client.get(f"/api/evaluations/x/answers.{fmt}", headers=ADMIN).status_code == 422
    assert (
        client.get(f"/api/evaluations/{answered['id']}/answers.xml", headers=ADMIN).status_code
        == 404
    )


def test_the_evaluation_page_links_the_exports(client, answered) -> None:
    html = logged_in(client).get(f"/evaluations/{answered['id']}").text
    for fmt in ("csv", "jsonl", "parquet"):
        assert f'href="/api/evaluations/{answered["id"]}/answers.{fmt}"' in html


def test_the_reminder_shows_the_advisors_own_bracket_and_is_recorded_per_answer(
    client, run_id, run_study
) -> None:
    advisor = _player(client, run_study["id"])
    evaluation_id = _advisor_evaluation(client, run_id, advisor.id)
    ((_, who),) = _bearers(client, evaluation_id, 1)
    pair = client.get("/api/evaluators/me/pairs/next", headers=who).json()
    shown = pair["reminder"]
    # 3 candidates: the final's winner, its other player, the first round's loser
    assert [p["url"] for p in shown] == [
        f"/api/evaluators/me/reminder/{place}" for place in ("first", "second", "third")
    ]
    assert shown[0]["alt"] == "your choice in the final"
    assert set(pair) == {"key", "position", "total", "question", "left", "right", "reminder"}
    assert not {"run", "advised", "baseline", "slot", "arm"} & set(json.dumps(pair).split('"'))
    picture = client.get(shown[0]["url"], headers=who)
    assert picture.status_code == 200 and picture.headers["content-type"].startswith("image/")
    assert client.get(shown[0]["url"]).status_code == 401
    assert client.get("/api/evaluators/me/reminder/fourth", headers=who).status_code == 404
    assert client.get("/api/evaluators/me/reminder/3", headers=who).status_code == 422
    _answer(client, who, "right", "still")
    rows = [json.loads(line) for line in _get(client, evaluation_id, "jsonl").text.splitlines()]
    assert [r["reminder"] for r in rows] == [True]
    table = pq.read_table(io.BytesIO(_get(client, evaluation_id, "parquet").content))
    assert table.column("reminder").to_pylist() == [True]
    assert list(csv.DictReader(io.StringIO(_get(client, evaluation_id, "csv").text)))[0][
        "reminder"
    ] in ("True", "true", "1")


def test_no_reminder_when_it_is_off_or_for_others(client, run_id) -> None:
    evaluation_id = bare_evaluation(client, run_id=run_id)  # others, reminder off
    ((_, who),) = _bearers(client, evaluation_id, 1)
    assert client.get("/api/evaluators/me/pairs/next", headers=who).json()["reminder"] is None
    assert client.get("/api/evaluators/me/reminder/first", headers=who).status_code == 404


@pytest.mark.parametrize(
    "design",
    [{"show_bracket": True}, {"show_bracket": "true"}, {"show_bracket": 1}],
)
def test_show_bracket_is_strict_and_for_the_advisor_only(client, run_id, design) -> None:
    body = {
        "advised_run_ids": [run_id, run_id + 1],
        "baseline_run_ids": [run_id + 2, run_id + 3],
    } | design
    refused = client.post("/api/evaluations", json=body, headers=ADMIN)
    assert refused.status_code == 422, refused.text
    if design["show_bracket"] is True:
        assert "advisor only" in refused.json()["detail"]


def test_the_study_dataset_has_the_sharing_evaluators_answers(
    client, run_id, run_study, tmp_path
) -> None:
    study_id = run_study["id"]
    labeller = _player(client, study_id)  # the labels the dataset needs
    assert client.put(
        "/api/participants/me/share-consent", json={"share": True}, headers=labeller.headers
    ).json() == {"share": True}
    advisor = _player(client, study_id)
    evaluation_id = _advisor_evaluation(client, run_id, advisor.id)
    (sharer_id, sharer), (quiet_id, quiet) = _bearers(client, evaluation_id, 2)
    share = "/api/evaluators/me/share-consent"
    assert client.put(share, json={"share": "yes"}, headers=sharer).status_code == 422
    assert client.put(share, json={"share": True}).status_code == 401
    assert client.put(share, json={"share": True}, headers=sharer).json() == {"share": True}
    assert client.put(share, json={"share": False}, headers=quiet).json() == {"share": False}
    _answer(client, sharer, "left", "clip")
    _answer(client, sharer, "tie", "still")
    _answer(client, quiet, "right", "clip")

    response = export(client, study_id)
    assert response.status_code == 200, response.text
    folder = unzipped(response.content, tmp_path / "zip")
    configs = [c["config_name"] for c in card(folder)["configs"]]
    assert (
        configs[-1] == "evaluations"
        and "## Agent evaluations" in (folder / "README.md").read_text()
    )
    table = load_dataset(str(folder), "evaluations", cache_dir=str(tmp_path / "c"), split="train")
    rows = [r for r in table.to_list() if r["evaluation"] == evaluation_id]
    assert len(rows) == 2  # the quiet evaluator's answer is not shared
    assert {r["evaluator"] for r in rows} != {str(sharer_id)} and all(
        PSEUDONYM.fullmatch(r["evaluator"]) for r in rows
    )
    assert len({r["evaluator"] for r in rows}) == 1
    assert [r["position"] for r in rows] == [0, 1]
    assert [r["stimulus"] for r in rows] == ["clip", "still"]
    assert [r["winner"] for r in rows] == ["left", None] and [r["tie"] for r in rows] == [
        False,
        True,
    ]
    assert all(r["reminder"] is True for r in rows)
    assert all(r["evaluator_kind"] == "advisor" for r in rows)
    for r in rows:
        assert {r["left_arm"], r["right_arm"]} <= {"advised", "baseline"}
        assert PSEUDONYM.fullmatch(r["left_run"]) and r["left_run"] != str(run_id)
        assert len(r["answered_on"]) == 10 and r["answered_on"][4] == "-"
    assert str(quiet_id) not in {r["evaluator"] for r in table.to_list()}


def test_the_instructions_page_records_the_evaluators_choice(client, run_id) -> None:
    evaluation_id = bare_evaluation(client, run_id=run_id)
    made = client.post(
        f"/api/evaluations/{evaluation_id}/evaluators", json={"count": 1}, headers=ADMIN
    ).json()[0]
    page = TestClient(client.app, follow_redirects=False)
    assert page.get(made["invite_url"]).status_code in (303, 307)
    csrf = csrf_token(page, "/evaluate")
    html = page.get("/evaluate").text
    assert 'id="share"' in html and "Your answers will not be shared." in html
    assert page.post("/evaluate/share", data={"share": "on"}).status_code == 403  # no CSRF
    saved = page.post("/evaluate/share", data={"csrf_token": csrf, "share": "on"})
    assert saved.status_code == 303 and saved.headers["location"] == "/evaluate#share-form"
    assert "You agreed: your answers may be shared." in page.get("/evaluate").text
    page.post("/evaluate/share", data={"csrf_token": csrf})  # unticked: withdrawn
    assert "Your answers will not be shared." in page.get("/evaluate").text


def test_a_clip_is_refused_where_the_pair_was_shown_as_stills(client, run_id) -> None:
    """The stimulus column says what was seen: a stills evaluation records no clip, and an
    answer that names none records the pair's own kind."""
    evaluation_id = bare_evaluation(client, run_id=run_id)  # stills
    ((_, who),) = _bearers(client, evaluation_id, 1)
    key = client.get("/api/evaluators/me/pairs/next", headers=who).json()["key"]
    url = f"/api/evaluators/me/pairs/{key}"
    missing = client.get(f"{url}/left/still", headers=who)  # a bare evaluation's files: none
    assert missing.status_code == 404 and "missing on disk" in missing.json()["detail"]
    refused = client.post(url, json={"choice": "left", "stimulus": "clip"}, headers=who)
    assert refused.status_code == 422 and "no clips" in refused.json()["detail"]
    assert client.post(url, json={"choice": "left"}, headers=who).status_code == 200
    rows = [json.loads(line) for line in _get(client, evaluation_id, "jsonl").text.splitlines()]
    assert [r["stimulus"] for r in rows] == ["still"]
