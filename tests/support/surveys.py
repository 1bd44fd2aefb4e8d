"""Helpers of the survey tests: finished participants, a run checkpoint with stored agent
trees, survey bodies and respondents driving the API with their invite tokens."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import httpx
from fastapi.testclient import TestClient

from app.models import CheckpointArtefact, Run
from tests.support.browser import ADMIN_TOKEN as SERVER_ADMIN_TOKEN
from tests.support.evaluations import evaluator_headers
from tests.support.labelling import label_bracket, wait_until_prepared
from tests.support.server import HTTP_TIMEOUT_S
from tests.support.studies import Member, Player
from tests.support.web import ADMIN


def finished(client: TestClient, study_id: int, side: str = "a") -> int:
    """A participant who labelled the whole bracket, always choosing ``side``."""
    body = client.post(f"/api/studies/{study_id}/participants", headers=ADMIN).json()
    player = Player(client, body["id"], body["token"], body["invite_url"])
    player.play(lambda m: m[side]["candidate_id"])
    return body["id"]


def participant_trees(client: TestClient, study_id: int) -> tuple[dict[str, Any], ...]:
    """Two finished participants' trees (one always picks side a, one side b), as the
    stimulus sources of a survey body."""
    return tuple(
        {"kind": "participant", "participant_id": finished(client, study_id, side)}
        for side in ("a", "b")
    )


def tree_json(client: TestClient, participant_id: int) -> dict[str, Any]:
    response = client.get(f"/api/participants/{participant_id}/tree", headers=ADMIN)
    assert response.status_code == 200, response.text
    return response.json()


def run_with_artefact(
    client: TestClient,
    study_id: int,
    tree: dict[str, Any],
    *,
    step: int = 256,
    judge: str = "shaped",
) -> int:
    """A finished run row whose checkpoint ``step`` holds ``tree`` as the judge's agent tree
    (what the run executor stores; no training here)."""
    with client.app.state.runtime.sessions() as session:
        run = Run(
            study_id=study_id,
            teacher="standing",
            algo="bipars-em",
            timesteps=step,
            seed=0,
            n_envs=1,
            config={},
            status="succeeded",
            progress=step,
        )
        session.add(run)
        session.flush()
        session.add(
            CheckpointArtefact(
                run_id=run.id,
                step=step,
                payload={
                    "schema": "acv.checkpoint/1",
                    "step": step,
                    "judges": {judge: {"tree": tree | {"judge": f"agent:{judge}"}}},
                },
            )
        )
        session.commit()
        return run.id


def paper_body(tree1: dict[str, Any], tree2: dict[str, Any], **extra: Any) -> dict[str, Any]:
    """The paper's survey on one stimulus, with an attention check."""
    return {
        "name": "Paper study",
        "intro": "Two trees per screen.",
        "template": "paper",
        "stimuli": [{"label": "Case 2", "tree1": tree1, "tree2": tree2}],
        "attention_check": {"question": "q1", "expected": "same"},
    } | extra


@dataclass
class Respondent(Member):
    """A respondent answering their screens."""

    def screen(self) -> dict[str, Any] | None:
        response = self.client.get("/api/surveys/me/screen", headers=self.headers)
        assert response.status_code in (200, 204), response.text
        return response.json() if response.status_code == 200 else None

    def answer(self, position: int, answers: dict[str, Any], screen_ms: int = 1000):
        return self.client.post(
            f"/api/surveys/me/screens/{position}/answers",
            headers=self.headers,
            json={"answers": answers, "screen_ms": screen_ms},
        )


def invite(client: TestClient, survey_id: int, count: int = 1) -> list[Respondent]:
    response = client.post(
        f"/api/surveys/{survey_id}/respondents", json={"count": count}, headers=ADMIN
    )
    assert response.status_code == 201, response.text
    return [Respondent(client, r["id"], r["token"], r["invite_url"]) for r in response.json()]


def paper_answers(
    screen: dict[str, Any], q1: str = "different", q2: str = "yes", confidence: int = 4
) -> dict[str, Any]:
    """Answers to a paper screen (an attention check asks only q1)."""
    picks = {"q1": q1, "q2": q2}
    return {
        q["key"]: {"value": picks[q["key"]], "confidence": confidence} for q in screen["questions"]
    }


def scheme_headers(client: TestClient, study_id: int) -> dict[str, dict[str, str]]:
    """Headers per security scheme of the API: the researcher, a participant of the study,
    a respondent of a new survey over two of its finished participants, and an evaluator."""
    participant = client.post(f"/api/studies/{study_id}/participants", headers=ADMIN)
    human, other = finished(client, study_id, "a"), finished(client, study_id, "b")
    survey = client.post(
        "/api/surveys",
        headers=ADMIN,
        json=paper_body(
            {"kind": "participant", "participant_id": human},
            {"kind": "participant", "participant_id": other},
        ),
    )
    assert survey.status_code == 201, survey.text
    [respondent] = invite(client, survey.json()["id"])
    return {
        "AdminToken": ADMIN,
        "InviteToken": {"Authorization": f"Bearer {participant.json()['token']}"},
        "SurveyInviteToken": respondent.headers,
        "EvaluatorInviteToken": evaluator_headers(client),
    }


#: A screen is shown and answerable (as a function: Playwright evaluates a bare expression
#: string with eval, which the pages' policy forbids).
READY = "() => document.getElementById('respond').dataset.ready === 'true'"


def two_finished_participants(base: str) -> int:
    """A ready 5-candidate study with two finished participants (API); returns the study."""
    admin = {"Authorization": f"Bearer {SERVER_ADMIN_TOKEN}"}  # the browser tests' server
    with httpx.Client(base_url=base, headers=admin, timeout=HTTP_TIMEOUT_S) as api:
        study = api.post(
            "/api/studies",
            json={"name": "Survey trees", "env_id": "Hopper-v5", "n_candidates": 5, "seed": 4},
        ).json()
        wait_until_prepared(api, study["id"])
        for side in ("a", "b"):
            token = api.post(f"/api/studies/{study['id']}/participants").json()["token"]
            label_bracket(api, token, lambda match, side=side: match[side]["candidate_id"])
    return study["id"]
