"""Imported policies on the researcher's pages, rendered by the app (issue 44 §2): the
external experiment's page, an imported policy's comparison, run and list pages, with the
declared training beside "ACV did not see them train" and nothing the CSP would block; and a
participant's advice frozen for the policies that trained on it. Nothing is judged here; the
browser test (tests/app/runs/test_agents_browser.py) shows them judged, checked by axe.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.support.agents import DECLARED, create_external, policy, upload
from tests.support.runs import finished_participant, run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN, audit, logged_in

# postgres_only: pages are the subject, not storage.
pytestmark = pytest.mark.postgres_only


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client, seed=8)


def test_the_pages_show_imported_policies(client: TestClient, study: dict[str, Any]) -> None:
    experiment = create_external(client, study["id"])
    tree = experiment["spec"]["tree_sha256"]
    page = logged_in(client)
    empty = page.get(f"/experiments/{experiment['id']}").text
    assert "No policy imported yet" in empty and tree in empty and audit(empty) == []
    run = upload(
        client, experiment["id"], policy(31), arm="advised", seed=4, tree_sha256=tree, **DECLARED
    ).json()
    html = page.get(f"/experiments/{experiment['id']}").text
    assert f'data-imported="{run["imported"]["onnx_sha256"]}"' in html
    assert "ACV did not see them train" in html and "sb3 PPO, 100,000 steps" in html
    assert "the experiment&#39;s" in html and audit(html) == []
    assert 'value="shaped"' not in html  # imported policies have no diagnostic judges
    compare = page.get(f"/runs/{run['id']}/compare?judge=shaped").text
    assert "A policy trained elsewhere" in compare and "ACV did not see them train" in compare
    assert 'data-judge="return"' in compare and audit(compare) == []
    several = page.get(f"/runs/{run['id']}/compare-runs")
    assert several.status_code == 200 and "imported advised policy" in several.text
    assert audit(several.text) == []
    listed = page.get(f"/runs?study_id={study['id']}").text
    assert "imported: sb3 PPO" in listed and audit(listed) == []
    run_page = page.get(f"/runs/{run['id']}").text
    assert "imported advised policy" in run_page and audit(run_page) == []


def test_a_participant_s_advice_is_frozen_for_their_imported_policies(
    client: TestClient, study: dict[str, Any]
) -> None:
    person = finished_participant(client, study["id"])
    experiment = create_external(client, study["id"], participant_id=person)
    tree = client.get(f"/api/participants/{person}/tree", headers=ADMIN).json()
    assert experiment["spec"]["participant_id"] == person
    form = {"arm": "advised", "seed": 0, "tree_sha256": "0" * 64, **DECLARED}
    run = upload(client, experiment["id"], policy(41), **form).json()
    assert run["participant_id"] == person and run["advice"] == f"participant #{person}"
    assert run["imported"]["tree_matches"] is False  # another tree's hash: shown, not refused
    advice = client.get(f"/api/runs/{run['id']}/advice-tree", headers=ADMIN).json()
    assert advice["matches"] == tree["matches"]
