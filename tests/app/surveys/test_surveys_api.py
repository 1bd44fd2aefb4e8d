"""The survey API on SQLite and PostgreSQL: creating surveys from participants' trees, stored
agent trees and uploads; bad input answered with 4xx JSON; respondents' screens, final
answers and resumption; results with and without exclusions; exports."""

from __future__ import annotations

import copy
import csv
import io
import json
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.surveys.respond import DRAWN_NODE_FIELDS
from tests.support.studies import Player
from tests.support.surveys import (
    finished,
    invite,
    paper_answers,
    paper_body,
    run_with_artefact,
    tree_json,
)
from tests.support.web import ADMIN, logged_in


@pytest.fixture(scope="module")
def trees(client: TestClient, study: dict[str, Any]) -> dict[str, Any]:
    """Two finished participants (one always picks side a, one side b) and a run whose
    checkpoint 256 holds the second one's tree as its "shaped" agent tree."""
    straight, bent = finished(client, study["id"], "a"), finished(client, study["id"], "b")
    run_id = run_with_artefact(client, study["id"], tree_json(client, bent))
    return {
        "study": study["id"],
        "human": {"kind": "participant", "participant_id": straight},
        "agent": {"kind": "run", "run_id": run_id, "checkpoint": 256, "judge": "shaped"},
        "bent_doc": tree_json(client, bent),
        "run_id": run_id,
    }


def create(client: TestClient, body: dict[str, Any]) -> dict[str, Any]:
    response = client.post("/api/surveys", json=body, headers=ADMIN)
    assert response.status_code == 201, response.text
    return response.json()


def test_paper_survey_freezes_both_trees(client, trees) -> None:
    survey = create(client, paper_body(trees["human"], trees["agent"]))
    assert [q["key"] for q in survey["questions"]] == ["q1", "q2"]
    assert survey["questions"][1]["text"] == (
        "Tree 1 prefers a straight posture. Does Tree 2 prefer a bent posture?"
    )
    assert survey["exclusion_rule"] == "exclude respondents who fail the attention check"
    full = client.get(f"/api/surveys/{survey['id']}", headers=ADMIN).json()
    main, check = full["stimuli"]
    assert [t["name"] for t in main["trees"]] == ["Tree 1", "Tree 2"]
    assert main["trees"][1]["doc"]["judge"] == "agent:shaped"
    assert main["trees"][1]["source"] == trees["agent"]
    assert main["trees"][0]["highlight"]  # the two trees disagree: marks exist, shown or not
    assert check["attention_check"] and check["expected"] == {"q1": "same"}
    assert check["trees"][0]["doc"] == check["trees"][1]["doc"] == main["trees"][0]["doc"]


def test_uploads_and_blank_questions(client, trees) -> None:
    body = {
        "name": "Own questions",
        "template": "blank",
        "questions": [
            {
                "kind": "choice",
                "text": "Which tree prefers standing?",
                "options": ["Tree 1", "Tree 2", "Neither"],
                "expected": "Tree 1",
                "confidence": True,
            },
            {"kind": "likert", "text": "The trees are easy to read.", "points": 7},
            {"kind": "text", "text": "What does Tree 2 prefer?"},
        ],
        "stimuli": [
            {
                "tree1": trees["human"],
                "tree2": {"kind": "upload", "doc": trees["bent_doc"], "study_id": trees["study"]},
            }
        ],
        "assignment": "round_robin",
        "highlights": True,
        "seed": 5,
    }
    survey = create(client, body)
    assert [q["options"] for q in survey["questions"][1:]] == [
        ["1", "2", "3", "4", "5", "6", "7"],
        [],
    ]
    assert survey["exclusion_rule"].startswith("no exclusions")
    [respondent] = invite(client, survey["id"])
    screen = respondent.screen()
    shown = {screen[side]["name"]: screen[side]["highlight"] for side in ("left", "right")}
    assert shown["Tree 1"] and shown["Tree 2"]  # highlights on: the overturned matches
    assert [q["kind"] for q in screen["questions"]] == ["choice", "likert", "text"]


@pytest.mark.parametrize(
    "path, value",
    [
        (("seed",), True),
        (("seed",), 1.5),
        (("seed",), "1"),
        (("highlights",), 1),
        (("stimuli", 0, "tree1", "participant_id"), True),
        (("stimuli", 0, "tree2", "checkpoint"), "256"),
        (("stimuli", 0, "tree2", "checkpoint"), 2.5),
        (("template",), "other"),
        (("assignment",), "random"),
        (("stimuli",), []),
        (("stimuli", 0, "tree1", "kind"), "file"),
        (("name",), ""),
        (("extra",), 1),
    ],
)
def test_bad_bodies_are_422_json(client, trees, path, value) -> None:
    body = copy.deepcopy(paper_body(trees["human"], trees["agent"]))
    target = body
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    response = client.post("/api/surveys", json=body, headers=ADMIN)
    assert response.status_code == 422, response.text
    assert response.json()["detail"]


@pytest.mark.parametrize(
    "tree2, status, words",
    [
        ({"kind": "run", "run_id": 1, "checkpoint": 999, "judge": "shaped"}, 409, "not computed"),
        ({"kind": "run", "run_id": 2**31 - 1, "checkpoint": 256, "judge": "shaped"}, 404, "run"),
        ({"kind": "participant", "participant_id": 2**31 - 1}, 404, "participant"),
        ({"kind": "upload", "doc": {"schema": "acv.tree/1"}}, 422, "acv.tree/1"),
        ({"kind": "upload", "doc": {"schema": "nope"}}, 422, "acv.tree/1"),
    ],
)
def test_unusable_trees_are_refused(client, trees, tree2, status, words) -> None:
    if tree2["kind"] == "run" and tree2["run_id"] == 1:
        tree2 = tree2 | {"run_id": trees["run_id"]}
    response = client.post("/api/surveys", json=paper_body(trees["human"], tree2), headers=ADMIN)
    assert response.status_code == status, response.text
    assert words in response.json()["detail"]


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity", "1e999"])
@pytest.mark.parametrize("where", ["env_reward", "score", "r_b", "r_e"])
def test_uploads_with_non_finite_numbers_are_422(client, trees, where: str, token: str) -> None:
    doc = copy.deepcopy(trees["bent_doc"])
    if where == "env_reward":
        doc["candidates"][0]["env_reward"] = "@NUMBER@"
    elif where == "score":
        for c in doc["candidates"]:
            c["score"] = 1.0
        doc["candidates"][1]["score"] = "@NUMBER@"
    else:
        doc["tree_reward"][where] = "@NUMBER@"
    body = paper_body(trees["human"], {"kind": "upload", "doc": doc})
    text = json.dumps(body).replace('"@NUMBER@"', token)  # JSON text as a client may send it
    response = client.post(
        "/api/surveys", content=text, headers=ADMIN | {"Content-Type": "application/json"}
    )
    assert response.status_code == 422, response.text
    assert "must be a finite number" in response.json()["detail"]


#: Places of numbers in an uploaded tree, as the refusal names them, and their keys.
NUMBER_PLACES = {
    "candidates[0].env_reward": ("candidates", 0, "env_reward"),
    "candidates[1].score": ("candidates", 1, "score"),
    "candidates[0].qpos[0]": ("candidates", 0, "qpos", 0),
    "tree_reward.r_b": ("tree_reward", "r_b"),
    "seed": ("seed",),
    "p": ("p",),
    "matches[0].winner": ("matches", 0, "winner"),
}


@pytest.mark.parametrize("flag", [True, False])
@pytest.mark.parametrize("place", sorted(NUMBER_PLACES))
def test_uploads_with_booleans_for_numbers_are_422(client, trees, place: str, flag) -> None:
    """``env_reward: true`` is not a reward of 1 (the tree reader would take it for one): a
    boolean where a number belongs is refused, as in every request body (issue 45 §6)."""
    doc = copy.deepcopy(trees["bent_doc"])
    for c in doc["candidates"]:
        c["score"] = 1.0
    *parents, last = NUMBER_PLACES[place]
    holder = doc
    for key in parents:
        holder = holder[key]
    holder[last] = flag
    body = paper_body(trees["human"], {"kind": "upload", "doc": doc})
    response = client.post("/api/surveys", json=body, headers=ADMIN)
    assert response.status_code == 422, response.text
    assert f"'{place}' is {str(flag).lower()}" in response.json()["detail"]


def test_a_matchs_tie_flag_is_the_one_boolean_of_an_upload(client, trees) -> None:
    doc = copy.deepcopy(trees["bent_doc"])
    doc["matches"][0]["tie"] = False  # absent means false: the same tree
    create(client, paper_body(trees["human"], {"kind": "upload", "doc": doc}))


def test_semantic_errors_name_the_problem(client, trees, invite) -> None:
    unknown_judge = trees["agent"] | {"judge": "value"}
    response = client.post(
        "/api/surveys", json=paper_body(trees["human"], unknown_judge), headers=ADMIN
    )
    assert response.status_code == 422 and "it has: shaped" in response.json()["detail"]
    unfinished = {"kind": "participant", "participant_id": invite().id}
    response = client.post(
        "/api/surveys", json=paper_body(unfinished, trees["agent"]), headers=ADMIN
    )
    assert response.status_code == 409 and "not finished" in response.json()["detail"]
    body = paper_body(
        trees["human"], trees["agent"], attention_check={"question": "q2", "expected": "maybe"}
    )
    response = client.post("/api/surveys", json=body, headers=ADMIN)
    assert response.status_code == 422 and "'maybe'" in response.json()["detail"]
    body = {
        "name": "x",
        "template": "blank",
        "questions": [{"kind": "choice", "text": "?", "options": ["a"], "expected": None}],
        "stimuli": [{"tree1": trees["human"], "tree2": trees["agent"]}],
    }
    response = client.post("/api/surveys", json=body, headers=ADMIN)
    assert response.status_code == 422 and "2..6 distinct" in response.json()["detail"]


def test_researcher_routes_need_credentials(client, trees) -> None:
    survey = create(client, paper_body(trees["human"], trees["agent"]))
    [respondent] = invite(client, survey["id"])
    for path in (
        "/api/surveys",
        f"/api/surveys/{survey['id']}/results",
        f"/api/surveys/{survey['id']}/answers.csv",
    ):
        assert client.get(path).status_code == 401
        assert client.get(path, headers=respondent.headers).status_code == 401
    assert client.get("/api/surveys/me/screen").status_code == 401
    assert client.get("/api/surveys/me/screen", headers=ADMIN).status_code == 401
    assert client.get("/api/surveys/0/results", headers=ADMIN).status_code == 422
    assert client.get("/api/surveys/999999/results", headers=ADMIN).status_code == 404
    for count in (0, True, 1.5, "2", 501):
        response = client.post(
            f"/api/surveys/{survey['id']}/respondents", json={"count": count}, headers=ADMIN
        )
        assert response.status_code == 422, count


def test_answers_are_final_and_checked(client, trees) -> None:
    survey = create(client, paper_body(trees["human"], trees["agent"]))
    [r] = invite(client, survey["id"])
    screen = r.screen()
    assert screen["position"] == 1 and screen["total"] == 2
    if len(screen["questions"]) == 1:  # the attention check came first in this order
        assert r.answer(1, paper_answers(screen, q1="same")).status_code == 201
        screen = r.screen()
    assert [q["key"] for q in screen["questions"]] == ["q1", "q2"]
    assert "expected" not in json.dumps(screen["questions"])
    assert {screen["left"]["name"], screen["right"]["name"]} == {"Tree 1", "Tree 2"}
    assert screen["left"]["doc"]["judge"] in ("Tree 1", "Tree 2")  # whose tree stays hidden
    for side in ("left", "right"):  # the shape drawn, and nothing that tells an agent's tree
        doc = screen[side]["doc"]
        assert set(doc) == {"judge", "tree"} and set(doc["tree"]) == {"root", "nodes"}
        assert {k for n in doc["tree"]["nodes"] for k in n} == set(DRAWN_NODE_FIELDS)
    assert screen["left"]["highlight"] == screen["right"]["highlight"] == []  # off by default
    assert r.screen() == screen  # resumed: the same screen, the same placement
    good = paper_answers(screen)
    for bad in (
        {},
        {k: v for k, v in list(good.items())[:1]},
        good | {"q1": {"value": "maybe", "confidence": 3}},
        good | {"q1": {"value": "same"}},
        good | {"q1": {"value": "same", "confidence": 6}},
        good | {"q1": {"value": "same", "confidence": True}},
        good | {"q1": {"value": "same", "confidence": 2.5}},
        good | {"q9": {"value": "yes", "confidence": 2}},
    ):
        response = r.answer(screen["position"], bad)
        assert response.status_code == 422, (bad, response.text)
        assert response.json()["detail"]
    assert r.answer(screen["position"], good, screen_ms=-1).status_code == 422
    assert r.answer(screen["position"], good, screen_ms=True).status_code == 422
    assert r.answer(99, good).status_code == 404
    assert r.answer(screen["position"], good, screen_ms=4200).status_code == 201
    assert r.answer(screen["position"], good, screen_ms=10).status_code == 200  # same again
    changed = paper_answers(screen, q1="same")
    response = r.answer(screen["position"], changed)
    assert response.status_code == 409 and "final" in response.json()["detail"]
    following = r.screen()
    assert following is None or following["position"] == 2


def _finish(respondent, *, q1: str, q2: str, check: str, ms: int) -> None:
    while (screen := respondent.screen()) is not None:
        is_check = len(screen["questions"]) == 1
        answers = paper_answers(screen, q1=check if is_check else q1, q2=q2, confidence=3)
        assert respondent.answer(screen["position"], answers, screen_ms=ms).status_code == 201


def test_results_with_and_without_exclusions(client, trees) -> None:
    survey = create(client, paper_body(trees["human"], trees["agent"]))
    people = invite(client, survey["id"], count=4)
    _finish(people[0], q1="different", q2="yes", check="same", ms=1000)
    _finish(people[1], q1="different", q2="no", check="same", ms=3000)
    _finish(people[2], q1="same", q2="no", check="different", ms=5000)  # fails the check
    people[3].screen()  # started, nothing answered
    results = client.get(f"/api/surveys/{survey['id']}/results", headers=ADMIN).json()
    assert results["respondents"] == {
        "invited": 4,
        "started": 4,
        "finished": 3,
        "answered_attention_check": 3,
        "failed_attention_check": 1,
        "excluded": 1,
    }
    q1, q2 = results["without_exclusions"]
    assert (q1["n"], q1["counts"], q1["accuracy"]["k"]) == (3, {"same": 1, "different": 2}, 2)
    assert q1["accuracy"]["ci_low"] == pytest.approx(0.0943, abs=1e-4)  # 2/3 exact interval
    assert q1["accuracy"]["p_value"] == pytest.approx(1.0)
    assert (q2["counts"], q2["median_time_ms"], q2["mean_confidence"]) == (
        {"yes": 1, "no": 2},
        3000.0,
        3.0,
    )
    kept1, kept2 = results["with_exclusions"]
    assert (kept1["n"], kept1["accuracy"]["k"], kept1["accuracy"]["proportion"]) == (2, 2, 1.0)
    assert kept1["accuracy"]["ci_low"] == pytest.approx(0.025**0.5, rel=1e-9)
    assert kept2["counts"] == {"yes": 1, "no": 1} and kept2["median_time_ms"] == 2000.0
    assert [f["k"] for f in results["paper"]] == [20, 17]


def test_exports_have_one_row_per_answer(client, trees) -> None:
    survey = create(client, paper_body(trees["human"], trees["agent"]))
    [r] = invite(client, survey["id"])
    _finish(r, q1="different", q2="yes", check="different", ms=777)
    csv_text = client.get(f"/api/surveys/{survey['id']}/answers.csv", headers=ADMIN)
    assert csv_text.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(csv_text.text)))
    lines = client.get(f"/api/surveys/{survey['id']}/answers.jsonl", headers=ADMIN).text
    records = [json.loads(line) for line in lines.splitlines()]
    assert len(rows) == len(records) == 3  # q1 and q2, then q1 of the attention check
    assert {(x["question"], x["value"], x["attention_check"]) for x in records} == {
        ("q1", "different", False),
        ("q2", "yes", False),
        ("q1", "different", True),
    }
    assert all(x["excluded"] and x["screen_ms"] == 777 for x in records)
    assert [row["respondent_id"] for row in rows] == [str(r.id)] * 3
    assert {x["tree1_side"] for x in records} <= {"left", "right"}


def test_thumbnails_for_the_surveys_respondents_only(client, trees) -> None:
    survey = create(client, paper_body(trees["human"], trees["agent"]))
    other = create(client, paper_body(trees["human"], trees["agent"]))
    [mine], [theirs] = invite(client, survey["id"]), invite(client, other["id"])
    url = f"/api/surveys/{survey['id']}/studies/{trees['study']}/candidates/0/thumb"
    assert client.get(url, headers=mine.headers).status_code == 200
    assert client.get(url, headers=ADMIN).headers["content-type"].startswith("image/")
    assert client.get(url, headers=theirs.headers).status_code == 401
    assert client.get(url).status_code == 401
    assert (
        client.get(
            url.replace(f"studies/{trees['study']}", "studies/999999"), headers=mine.headers
        ).status_code
        == 404
    )


def test_sources_list_what_can_be_picked(client, trees) -> None:
    menus = client.get("/api/surveys/sources", headers=ADMIN).json()
    assert trees["human"]["participant_id"] in [p["participant_id"] for p in menus["participants"]]
    assert {
        "run_id": trees["run_id"],
        "checkpoint": 256,
        "algo": "bipars-em",
        "judges": ["shaped"],
    } in menus["checkpoints"]


def test_a_respondents_token_is_not_a_failed_researcher_login(client, trees) -> None:
    """Sent to researcher routes, a respondent's own token is refused (401) but not counted
    as a guess of the admin token: past the failed-login limit it is still 401, not 429."""
    survey = create(client, paper_body(trees["human"], trees["agent"]))
    [respondent] = invite(client, survey["id"])
    elsewhere = TestClient(client.app, client=("10.0.13.1", 40000))
    for _ in range(12):
        assert elsewhere.get("/api/surveys", headers=respondent.headers).status_code == 401
    guess = {"Authorization": "Bearer " + "x" * 43}
    statuses = [elsewhere.get("/api/surveys", headers=guess).status_code for _ in range(11)]
    assert statuses[0] == 401 and statuses[-1] == 429


def test_concurrent_submits_of_one_screen_store_one_answer(client, trees) -> None:
    """Six submits of the same screen at once, three of each answer: one is stored (201),
    the same again is 200, the other answer is 409; one set of answers is in the database."""
    survey = create(client, paper_body(trees["human"], trees["agent"]))
    [r] = invite(client, survey["id"])
    screen = r.screen()
    bodies = [paper_answers(screen, q1=q1) for q1 in ("same", "different") * 3]
    with ThreadPoolExecutor(max_workers=6) as pool:
        statuses = list(pool.map(lambda b: r.answer(screen["position"], b).status_code, bodies))
    assert statuses.count(201) == 1 and statuses.count(200) == 2
    assert statuses.count(409) == 3
    winner = bodies[statuses.index(201)]
    records = client.get(f"/api/surveys/{survey['id']}/answers.jsonl", headers=ADMIN).text
    stored = {json.loads(x)["question"]: json.loads(x)["value"] for x in records.splitlines()}
    assert stored == {k: v["value"] for k, v in winner.items()}


def test_free_text_answers_cannot_run_as_spreadsheet_formulas(client, trees) -> None:
    body = {
        "name": "Free text",
        "template": "blank",
        "questions": [{"kind": "text", "text": "What does Tree 2 prefer?"}],
        "stimuli": [{"tree1": trees["human"], "tree2": trees["agent"]}],
    }
    survey = create(client, body)
    [r] = invite(client, survey["id"])
    formula = '=HYPERLINK("http://x.example","bent")'
    assert r.answer(1, {"q1": {"value": formula}}).status_code == 201
    csv_text = client.get(f"/api/surveys/{survey['id']}/answers.csv", headers=ADMIN).text
    assert next(csv.DictReader(io.StringIO(csv_text)))["value"] == "'" + formula
    jsonl = client.get(f"/api/surveys/{survey['id']}/answers.jsonl", headers=ADMIN).text
    assert json.loads(jsonl)["value"] == formula  # JSONL keeps the answer as given
    results = client.get(f"/api/surveys/{survey['id']}/results", headers=ADMIN).json()
    assert results["without_exclusions"][0]["texts"] == [formula]


def test_likert_answers_are_tested_against_the_neutral_value(client, trees) -> None:
    """Not against chance = 1/points (issue 25 §6): a sign test around the scale's midpoint."""
    body = {
        "name": "Likert",
        "template": "blank",
        "questions": [
            {"kind": "likert", "text": "The trees are easy to read.", "points": 5, "expected": "5"}
        ],
        "stimuli": [{"tree1": trees["human"], "tree2": trees["agent"]}],
        "seed": 2,
    }
    survey = create(client, body)
    for person, value in zip(invite(client, survey["id"], count=4), "5435", strict=True):
        while (screen := person.screen()) is not None:
            answer = {"q1": {"value": value}}
            response = person.answer(screen["position"], answer)
            assert response.status_code == 201, response.text
    [block] = client.get(f"/api/surveys/{survey['id']}/results", headers=ADMIN).json()[
        "without_exclusions"
    ]
    assert block["accuracy"] is None  # a Likert answer is not right or wrong
    leaning = block["versus_neutral"]
    assert (leaning["neutral"], leaning["above"], leaning["below"], leaning["at"]) == (3, 3, 0, 1)
    assert leaning["p_value"] == pytest.approx(2 * 0.5**3)  # exact two-sided sign test
    page = logged_in(client).get(f"/surveys/{survey['id']}")
    assert "3 above, 0 below, 1 at the neutral 3" in page.text


def test_security_entries_list_every_scheme_that_works(client, trees) -> None:
    """The participant tree, candidate image and survey thumbnail operations document as
    OpenAPI ``security`` exactly the bearer schemes whose tokens they accept."""
    survey = create(client, paper_body(trees["human"], trees["agent"]))
    [respondent] = invite(client, survey["id"])
    body = client.post(f"/api/studies/{trees['study']}/participants", headers=ADMIN).json()
    Player(client, body["id"], body["token"], body["invite_url"]).play()
    tokens = {
        "AdminToken": ADMIN["Authorization"],
        "InviteToken": f"Bearer {body['token']}",
        "SurveyInviteToken": respondent.headers["Authorization"],
    }
    operations = {
        "/api/participants/{participant_id}/tree": f"/api/participants/{body['id']}/tree",
        "/api/studies/{study_id}/candidates/{candidate_id}/image": (
            f"/api/studies/{trees['study']}/candidates/0/image"
        ),
        "/api/surveys/{survey_id}/studies/{study_id}/candidates/{candidate_id}/thumb": (
            f"/api/surveys/{survey['id']}/studies/{trees['study']}/candidates/0/thumb"
        ),
    }
    paths = client.app.openapi()["paths"]
    for template, url in operations.items():
        documented = {name for entry in paths[template]["get"]["security"] for name in entry}
        works = {
            scheme
            for scheme, token in tokens.items()
            if client.get(url, headers={"Authorization": token}).status_code == 200
        }
        assert documented == works, template
