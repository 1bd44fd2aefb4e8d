"""Studies and participants through the REST API: a ready study, a participant's whole
bracket played with their invite token."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fastapi.testclient import TestClient

from tests.support.wait import wait_for
from tests.support.web import ADMIN


def wait_ready(client: TestClient, study_id: int, timeout_s: float = 60.0) -> dict[str, Any]:
    """Poll a study until it leaves ``preparing``; returns its JSON."""
    return wait_for(
        lambda: client.get(f"/api/studies/{study_id}", headers=ADMIN).json(),
        lambda body: body["status"] != "preparing",
        what=f"study {study_id} to leave preparing",
        timeout_s=timeout_s,
        every_s=0.05,
    )


def new_study(client: TestClient, **overrides: Any) -> dict[str, Any]:
    """Create a small Hopper study and wait until it is prepared."""
    body = {
        "name": "test study",
        "env_id": "Hopper-v5",
        "n_candidates": 5,
        "p": 0.9,
        "seed": 3,
        "sampling": "uniform",
        "instructions": "Pick the taller one.",
    }
    response = client.post("/api/studies", json=body | overrides, headers=ADMIN)
    assert response.status_code == 201, response.text
    return wait_ready(client, response.json()["id"])


@dataclass
class Member:
    """Someone invited to a collection (a study's participant, a survey's respondent),
    driving the REST API with their invite token."""

    client: TestClient
    id: int
    token: str
    invite_url: str

    @property
    def headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"}


@dataclass
class Player(Member):
    """A participant playing their bracket."""

    def next_match(self) -> dict[str, Any] | None:
        response = self.client.get("/api/participants/me/next-match", headers=self.headers)
        assert response.status_code in (200, 204), response.text
        return response.json() if response.status_code == 200 else None

    def label(self, match_id: int, winner: int, **extra: Any):
        return self.client.post(
            f"/api/matches/{match_id}/label", headers=self.headers, json={"winner": winner, **extra}
        )

    def answer_gold(self, item_id: int, winner: int):
        return self.client.post(
            f"/api/participants/me/gold/{item_id}/label",
            headers=self.headers,
            json={"winner": winner},
        )

    def play(self, choose: Callable[[dict[str, Any]], int] | None = None) -> int:
        """Label every match (``choose`` picks the winner; default the ``a`` side), and
        answer any gold item shown between them the same way; returns the labels sent."""
        sent = 0
        while (match := self.next_match()) is not None:
            winner = choose(match) if choose else match["a"]["candidate_id"]
            if match.get("gold"):
                assert self.answer_gold(match["gold"]["item_id"], winner).status_code == 201
                continue
            assert self.label(match["match_id"], winner).status_code == 201
            sent += 1
        return sent
