"""Experiments through the API: advised runs on k seeds, a matched baseline that is shared,
pilot runs, and the verdict read from the runs' stored checkpoint artefacts (issue 25 §1).

No run trains here (the run worker is off): each run's artefact is written as its executor
would write it, with per-candidate scores whose truth is known, so the verdict's outcome is
known. Training and judging for real are covered by the runs tests and the browser test.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select
from typer.testing import CliRunner

from app.cli.root import cli
from app.core.errors import ConflictError
from app.models import Experiment, Run, RunCheckpoint, RunStatus
from app.runs import artefacts, comparison, experiments
from engine.verdict import VerdictOptions
from tests.support.artefacts import report_body
from tests.support.labelling import label_bracket
from tests.support.runs import TINY, finished_participant, run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN, audit, csrf_token, logged_in

# postgres_only: training is the subject, not storage.
pytestmark = pytest.mark.postgres_only

BODY = {"algo": "bipars-em", "timesteps": 512, **TINY}
STEP = 256
SEED_SD = VerdictOptions().seed_sd


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client, n_candidates=8, seed=11)


def _create(client: TestClient, status: int = 202, **body: Any) -> dict[str, Any]:
    response = client.post("/api/experiments", json=body, headers=ADMIN)
    assert response.status_code == status, response.text
    return response.json()


def _n_runs(client: TestClient) -> int:
    with client.app.state.runtime.sessions() as session:
        return session.scalar(select(func.count()).select_from(Run))


def _write_artefact(client: TestClient, run_id: int, step: int, behaviour: np.ndarray) -> None:
    """The run's report at ``step`` as its executor stores it (only the table matters here)."""
    with client.app.state.runtime.sessions() as session:
        assert artefacts.store(session, run_id=run_id, step=step, body=report_body(step, behaviour))


def test_an_experiment_queues_advised_baseline_and_pilot_runs(client, study) -> None:
    created = _create(client, study_id=study["id"], teacher="good", seeds=3, pilot_seeds=2, **BODY)
    roles = [(r["role"], r["algo"], r["seed"]) for r in created["runs"]]
    assert roles == [
        ("advised", "bipars-em", 0),
        ("advised", "bipars-em", 1),
        ("advised", "bipars-em", 2),
        ("baseline", "ppo", 0),
        ("baseline", "ppo", 1),
        ("baseline", "ppo", 2),
        ("pilot", "ppo", 1_000_000),
        ("pilot", "ppo", 1_000_001),
    ]
    assert all(r["status"] == "queued" for r in created["runs"])
    assert created["seeds"] == [0, 1, 2] and created["pilot_seeds"] == [1_000_000, 1_000_001]
    # The resource links its verdict (pending until runs are judged).
    assert created["verdict_url"] == f"/api/experiments/{created['id']}/verdict"
    assert client.get(created["verdict_url"], headers=ADMIN).status_code == 202
    # Another advice source with the same settings reuses the baseline and pilot runs.
    before = _n_runs(client)
    other = _create(
        client, study_id=study["id"], teacher="standing", seeds=3, pilot_seeds=2, **BODY
    )
    assert _n_runs(client) == before + 3  # its own advised runs only
    shared = lambda e: [r["id"] for r in e["runs"] if r["role"] != "advised"]  # noqa: E731
    assert shared(other) == shared(created)
    # Other settings (the budget) are another baseline.
    third = _create(
        client,
        study_id=study["id"],
        teacher="good",
        seeds=2,
        pilot_seeds=1,
        **{**BODY, "timesteps": 1024},
    )
    assert not set(shared(third)) & set(shared(created))
    listed = client.get(f"/api/experiments?study_id={study['id']}", headers=ADMIN).json()
    assert [e["id"] for e in listed] == [created["id"], other["id"], third["id"]]


def test_a_ppo_run_without_advice_is_not_a_baseline(client) -> None:
    # Its checkpoints are never judged, so an experiment resting on it would wait for ever.
    study = new_study(client, n_candidates=4, seed=12)
    plain = client.post(
        "/api/runs", json={"study_id": study["id"], "seed": 0, **BODY, "algo": "ppo"}, headers=ADMIN
    )
    assert plain.status_code == 202, plain.text
    created = _create(client, study_id=study["id"], teacher="good", seeds=2, pilot_seeds=1, **BODY)
    baseline = [r for r in created["runs"] if r["role"] == "baseline" and r["seed"] == 0]
    assert baseline and baseline[0]["id"] != plain.json()["id"]


def test_the_verdict_waits_for_judged_runs_then_says_used(client, study) -> None:
    experiment = _create(
        client,
        study_id=study["id"],
        teacher="good",
        seeds=5,
        pilot_seeds=1,
        **{**BODY, "timesteps": 768},
    )
    path = f"/api/experiments/{experiment['id']}/verdict?judge=behaviour"
    assert client.get(path, headers=ADMIN).status_code == 202
    pending_csv = client.get(path.replace("verdict?", "verdict.csv?"), headers=ADMIN)
    assert pending_csv.status_code == 202 and pending_csv.json() == {"status": "pending"}
    advice = np.array(
        [
            c["env_reward"]
            for c in client.get(f"/api/studies/{study['id']}/candidates", headers=ADMIN).json()
        ]
    )
    rng = np.random.default_rng(0)
    for run in experiment["runs"]:  # advised runs follow the advice, the others go against it
        sign = 1.0 if run["role"] == "advised" else -1.0
        _write_artefact(client, run["id"], STEP, sign * advice + rng.normal(0, 1e-3, advice.size))
    _write_artefact(client, experiment["runs"][0]["id"], 2 * STEP, advice)  # one run further
    response = client.get(path, headers=ADMIN)
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["step"] == STEP  # the latest step judged in enough runs of every role
    assert sorted(body["runs"]) == ["advised", "baseline", "pilot"]
    assert (body["final"], body["diagnostic"]) == (False, False)  # the runs are still queued
    verdict = body["verdict"]
    assert verdict["outcome"] == "used", verdict
    assert verdict["ca_advised"] == [1.0] * 5 and verdict["ca_baseline"] == [0.0] * 5
    assert verdict["p_value"] < 0.05 and verdict["n_contested"] >= 3
    _the_verdict_as_csv(client, experiment, verdict, path.replace("verdict?", "verdict.csv?"))
    _the_verdict_on_the_runs_pages(client, experiment, '"interim"', "Interim: no verdict yet")
    _the_page_knows_its_verdict(client, experiment, body)

    final = 3 * STEP  # the runs' timesteps: their last checkpoint
    for run in experiment["runs"]:
        sign = 1.0 if run["role"] == "advised" else -1.0
        _write_artefact(client, run["id"], final, sign * advice + rng.normal(0, 1e-3, advice.size))
    ended = client.get(path, headers=ADMIN).json()
    assert (ended["step"], ended["final"], ended["verdict"]["outcome"]) == (final, True, "used")
    _the_verdict_on_the_runs_pages(client, experiment, '"used"', "Used your advice")
    shaped = client.get(path.replace("behaviour", "shaped"), headers=ADMIN).json()
    assert (shaped["final"], shaped["diagnostic"]) == (True, True)  # never an outcome word
    page = logged_in(client).get(f"/experiments/{experiment['id']}?judge=shaped").text
    assert 'data-outcome="diagnostic"' in page and "Diagnostic: no verdict" in page


def _the_page_knows_its_verdict(client: TestClient, experiment: dict, body: dict) -> None:
    """The experiment page's ``data-verdict-key`` is the key static/js/experiment.js makes of
    the verdict's JSON (the step, the sorted run ids, final or interim): the page reloads when
    it changes."""
    html = logged_in(client).get(f"/experiments/{experiment['id']}?judge=behaviour").text
    ids = ",".join(map(str, sorted(i for role in body["runs"].values() for i in role)))
    look = "final" if body["final"] else "interim"
    assert f'data-verdict-key="{body["step"]}:{ids}:{look}"' in html


def _the_verdict_as_csv(client: TestClient, experiment: dict, verdict: dict, path: str) -> None:
    """One row per run the verdict rests on: its role, seed and CA; the verdict on each."""
    response = client.get(path, headers=ADMIN)
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    assert (
        f"experiment-{experiment['id']}-verdict-behaviour-step{STEP}.csv"
        in (response.headers["content-disposition"])
    )
    rows = list(csv.DictReader(io.StringIO(response.text)))
    by_role = {role: [r for r in rows if r["role"] == role] for role in ("advised", "baseline")}
    seeds = {r["id"]: str(r["seed"]) for r in experiment["runs"]}
    assert [r["ca"] for r in by_role["advised"]] == ["1.0"] * 5
    assert [r["ca"] for r in by_role["baseline"]] == ["0.0"] * 5
    assert [(r["role"], r["ca"]) for r in rows[10:]] == [("pilot", "")]
    assert all(r["seed"] == seeds[int(r["run_id"])] for r in rows)
    assert {(r["outcome"], r["judge"], r["step"]) for r in rows} == {("used", "behaviour", "256")}
    assert {float(r["p_value"]) for r in rows} == {verdict["p_value"]}
    assert {int(r["contested_matches"]) for r in rows} == {verdict["n_contested"]}


def _the_verdict_on_the_runs_pages(
    client: TestClient, experiment: dict, outcome: str, words: str
) -> None:
    """An advised run's comparison pages give its experiment's verdict with the page's judge
    where that judge leads verdicts (its ``outcome`` and ``words``: an outcome word only once
    final); these artefacts have no return column, which they say."""
    page = logged_in(client)
    advised = experiment["runs"][0]["id"]
    note = f'<li data-experiment="{experiment["id"]}" data-outcome='
    shown = page.get(f"/runs/{advised}/compare?judge=behaviour").text
    assert note + outcome in shown and words in shown and audit(shown) == []
    experiment_page = page.get(f"/experiments/{experiment['id']}?judge=behaviour").text
    assert f"data-outcome={outcome}" in experiment_page and words in experiment_page
    diagnostic = page.get(f"/runs/{advised}/compare?judge=shaped").text  # never a verdict's
    assert note + '"unavailable"' in diagnostic and "without the &#39;return&#39; judge" in (
        diagnostic
    )
    assert note + '"unavailable"' in page.get(f"/runs/{advised}/compare-runs").text


@pytest.mark.parametrize(
    ("change", "says"),
    [
        ({"algo": "ppo"}, "algo other than ppo"),
        ({"seeds": 1}, "seeds"),
        ({"seeds": 21}, "seeds"),
        ({"seeds": True}, "seeds"),
        ({"pilot_seeds": 0}, "pilot_seeds"),
        ({"teacher": "nobody"}, "teacher"),
        ({"teacher": None}, "advice"),
        ({"study_id": 999_999}, "study"),
    ],
)
def test_bad_experiments_are_refused_and_queue_nothing(client, study, change, says) -> None:
    before = _n_runs(client)
    body = {"study_id": study["id"], "teacher": "good", **BODY, **change}
    response = client.post("/api/experiments", json=body, headers=ADMIN)
    assert 400 <= response.status_code < 500 and says in response.text, response.text
    assert _n_runs(client) == before


def test_a_failure_after_the_advised_runs_leaves_none_to_train(client, study, monkeypatch) -> None:
    """Each run commits as it is queued: when a later step fails (here the baselines', as a
    race in the shared store could), the advised runs already queued are cancelled and no
    experiment is left half made."""

    def fails(*_: Any) -> None:
        raise ConflictError("the shared store moved")

    monkeypatch.setattr(experiments, "_baseline_run", fails)
    with client.app.state.runtime.sessions() as session:
        last_run = session.scalar(select(func.max(Run.id))) or 0
        n_experiments = session.scalar(select(func.count()).select_from(Experiment))
    body = {"study_id": study["id"], "teacher": "good", **BODY, "seeds": 3}
    response = client.post("/api/experiments", json=body, headers=ADMIN)
    assert response.status_code == 409 and "shared store" in response.text
    with client.app.state.runtime.sessions() as session:
        queued = session.scalars(select(Run).where(Run.id > last_run)).all()
        assert session.scalar(select(func.count()).select_from(Experiment)) == n_experiments
    assert [r.status for r in queued] == [RunStatus.CANCELLED] * 3  # the 3 advised seeds


def test_unknown_experiments_and_judges(client, study) -> None:
    assert client.get("/api/experiments/999999", headers=ADMIN).status_code == 404
    assert client.get("/api/experiments/999999/verdict", headers=ADMIN).status_code == 404
    experiment = _create(client, study_id=study["id"], teacher="good", seeds=2, **BODY)
    response = client.get(
        f"/api/experiments/{experiment['id']}/verdict?judge=psychic", headers=ADMIN
    )
    assert response.status_code == 422
    assert client.get("/api/experiments", headers={}).status_code == 401


def test_a_step_that_is_no_checkpoint_of_the_runs_is_404(client, study) -> None:
    """A verdict at a step no run of the experiment saved is not pending (issue 45 §6): it is
    a 404 naming the step; past the documented maximum, the query is a 422."""
    experiment = _create(client, study_id=study["id"], teacher="good", seeds=2, **BODY)
    path = f"/api/experiments/{experiment['id']}/verdict"
    advised = experiment["runs"][0]["id"]
    _write_artefact(client, advised, STEP, np.zeros(8))  # judged, in too few runs
    with client.app.state.runtime.sessions() as session:  # saved, not judged yet
        session.add(RunCheckpoint(run_id=advised, step=2 * STEP))
        session.commit()
    for url in (path, f"{path}.csv"):
        for step in (STEP, 2 * STEP):
            response = client.get(url, params={"step": step}, headers=ADMIN)
            assert response.status_code == 202 and response.json() == {"status": "pending"}
        for step in (STEP + 1, 2**62):
            response = client.get(url, params={"step": step}, headers=ADMIN)
            assert response.status_code == 404, response.text
            assert f"no checkpoint at step {step};" in response.json()["detail"]
        response = client.get(url, params={"step": 2**63}, headers=ADMIN)
        assert response.status_code == 422 and response.json()["detail"][0]["loc"] == [
            "query",
            "step",
        ]
    documented = client.app.openapi()["paths"]["/api/experiments/{experiment_id}/verdict"]
    assert "no checkpoint of its runs" in documented["get"]["responses"]["404"]["description"]


def test_the_cli_queues_lists_and_gives_the_verdict(client, study, settings, monkeypatch) -> None:
    """``acv experiment`` on this module's database: the same service as the API."""
    monkeypatch.setenv("ACV_DATA_DIR", str(settings.data_dir))
    monkeypatch.setenv("DATABASE_URL", settings.sqlalchemy_url)
    created = CliRunner().invoke(
        cli,
        [
            "experiment",
            "create",
            "--study",
            str(study["id"]),
            "--teacher",
            "good",
            "--timesteps",
            "640",
            "--seeds",
            "2",
            "--pilot-seeds",
            "1",
        ],
    )
    assert created.exit_code == 0, created.output
    experiment_id = int(created.output.split()[1])
    assert created.output.count("\tadvised\t") == 2 and created.output.count("\tpilot\t") == 1
    listed = CliRunner().invoke(cli, ["experiment", "list", "--study", str(study["id"])])
    assert f"{experiment_id}\tstudy {study['id']}\tbipars-em\t2 seeds\t0/5 runs" in listed.output
    pending = CliRunner().invoke(cli, ["experiment", "verdict", str(experiment_id)])
    assert pending.exit_code == 2 and "too few judged runs" in pending.output
    psychic = ["experiment", "verdict", str(experiment_id), "--judge", "psychic"]
    unknown = CliRunner().invoke(cli, psychic)  # named as such, judged runs or not
    assert unknown.exit_code == 2 and "unknown judge 'psychic'" in unknown.output
    bad = CliRunner().invoke(
        cli,
        [
            "experiment",
            "create",
            "--study",
            str(study["id"]),
            "--timesteps",
            "640",
            "--teacher",
            "good",
            "--seeds",
            "1",
        ],
    )
    assert bad.exit_code == 2 and "seeds: Input should be greater than or equal to 2" in bad.output


def test_the_cli_pools_participants_as_the_api_does(client, settings, monkeypatch) -> None:
    """``acv experiment create --pool P --pool Q``: the API's ``participant_ids``, with its
    weighting; ``--all-participants``: every finished participant; a pool of one person, or
    a weighting without a pool, exits 2 with the service's message."""
    monkeypatch.setenv("ACV_DATA_DIR", str(settings.data_dir))
    monkeypatch.setenv("DATABASE_URL", settings.sqlalchemy_url)
    study = new_study(client, seed=14)
    people = [finished_participant(client, study["id"]) for _ in range(2)]
    args = ["experiment", "create", "--study", str(study["id"]), "--timesteps", "640"]
    args += ["--seeds", "2", "--pilot-seeds", "1"]

    def spec(*more: str) -> dict[str, Any]:
        created = CliRunner().invoke(cli, [*args, *more])
        assert created.exit_code == 0, created.output
        path = f"/api/experiments/{created.output.split()[1]}"
        return client.get(path, headers=ADMIN).json()["spec"]

    pooled = spec(
        "--pool", str(people[0]), "--pool", str(people[1]), "--pool-weighting", "reliability"
    )
    assert pooled["participant_ids"] == people and pooled["pool_weighting"] == "reliability"
    assert spec("--all-participants")["all_participants"] is True
    for more, message in [
        (["--pool", str(people[0])], "at least two"),
        (["--teacher", "good", "--pool-weighting", "reliability"], "weights a pool"),
        (["--pool", str(people[0]), "--pool", str(people[1]), "--teacher", "good"], "one advice"),
        # the API's bounds hold on the command line too, and nothing is stored
        (["--teacher", "good", "--advice-scale", "inf"], "advice_scale: Input should be"),
        (["--teacher", "good", "--n-envs", "5000"], "n_envs: Input should be less than"),
        (["--teacher", "good", "--seeds", "21"], "seeds: Input should be less than"),
    ]:
        before = _n_runs(client)
        refused = CliRunner().invoke(cli, [*args, *more])
        assert refused.exit_code == 2 and message in refused.output, refused.output
        assert _n_runs(client) == before


def test_the_run_form_starts_an_experiment_and_its_page_shows_it(client, study) -> None:
    page = logged_in(client)
    form = {
        "csrf_token": csrf_token(page, f"/runs/new?study_id={study['id']}"),
        "study_id": str(study["id"]),
        "advice": "teacher:good",
        "algo": "bipars-em",
        "timesteps": "896",
        "seed": "0",
        "n_envs": "1",
        "num_steps": "128",
        "experiment": "on",
        "seeds": "2",
    }
    response = page.post("/runs", data=form, follow_redirects=False)
    assert response.status_code == 303, response.text
    experiment_id = int(response.headers["location"].rsplit("/", 1)[1])
    experiment = client.get(f"/api/experiments/{experiment_id}", headers=ADMIN).json()
    assert [r["role"] for r in experiment["runs"]].count("advised") == 2
    shown = page.get(f"/experiments/{experiment_id}")
    assert shown.status_code == 200 and audit(shown.text) == []
    assert "No verdict yet" in shown.text and shown.text.count('<tr data-run-id="') == 6
    # Seeds out of range are shown next to the form's field, and nothing is queued.
    before = _n_runs(client)
    refused = page.post("/runs", data=form | {"seeds": "25"}, follow_redirects=False)
    assert refused.status_code == 422 and 'id="seeds"' in refused.text
    assert _n_runs(client) == before
    # ppo is one run: the box does not apply.
    single = page.post("/runs", data=form | {"algo": "ppo"}, follow_redirects=False)
    assert single.status_code == 303 and "/runs/" in single.headers["location"]
    # A run's comparison pages lead to its experiment's verdict, or say how to get one.
    advised = experiment["runs"][0]["id"]
    # A run on the same advice whose checkpoint lacks a judge's tree (judged before that judge
    # existed) shows no metrics there; the page still answers.
    _write_artefact(client, experiment["runs"][1]["id"], STEP, np.zeros(8))
    for path in (f"/runs/{advised}/compare", f"/runs/{advised}/compare-runs"):
        linked = page.get(path)
        assert f'href="/experiments/{experiment_id}"' in linked.text and audit(linked.text) == []
    alone = page.get(single.headers["location"] + "/compare")
    assert "start an experiment" in alone.text and "/experiments/" not in alone.text


def test_advice_scale_shapes_the_advised_runs_only(client, study) -> None:
    """A dose of advice (issue 27's positive controls): the baseline is the same ppo runs."""
    plain = _create(client, study_id=study["id"], teacher="good", seeds=2, **BODY)
    dosed = _create(client, study_id=study["id"], teacher="good", seeds=2, advice_scale=10, **BODY)
    runs = {
        r["id"]: client.get(f"/api/runs/{r['id']}", headers=ADMIN).json() for r in dosed["runs"]
    }
    shared = lambda e: [r["id"] for r in e["runs"] if r["role"] != "advised"]  # noqa: E731
    assert shared(dosed) == shared(plain)
    for run in dosed["runs"]:
        assert runs[run["id"]]["config"]["advice_scale"] == (10 if run["role"] == "advised" else 1)
    for bad in (0, -1, 101, True, "10"):
        response = client.post(
            "/api/experiments",
            json={"study_id": study["id"], "teacher": "good", "advice_scale": bad, **BODY},
            headers=ADMIN,
        )
        assert response.status_code == 422 and "advice_scale" in response.text, (bad, response.text)


def test_a_reliability_weighted_pool_shares_its_baseline(client) -> None:
    """Every run of an experiment on a reliability-weighted pool (baseline and pilot included:
    they are judged against its verdict) records the pool's weights; a second experiment on
    the same pool, with the same weights, reuses the baseline and pilot runs."""
    study = new_study(client, seed=13)
    people = [finished_participant(client, study["id"]) for _ in range(2)]
    body = {"study_id": study["id"], "participant_ids": people, "seeds": 2, "pilot_seeds": 1}
    first = _create(client, **body, pool_weighting="reliability", **BODY)
    assert first["spec"]["pool_weighting"] == "reliability"
    quality = client.get(f"/api/studies/{study['id']}/quality", headers=ADMIN).json()
    weights = [p["reliability"] for p in quality["participants"]]
    for member in first["runs"]:
        run = client.get(f"/api/runs/{member['id']}", headers=ADMIN).json()
        assert run["pool_weighting"] == "reliability" and run["config"]["pool_weights"] == weights
    before = _n_runs(client)
    second = _create(client, **body, pool_weighting="reliability", **BODY)
    assert _n_runs(client) == before + 2  # its own advised runs only
    shared = lambda e: [r["id"] for r in e["runs"] if r["role"] != "advised"]  # noqa: E731
    assert shared(second) == shared(first)
    plain = _create(client, **body, **BODY)  # the plain mean: another advice, another baseline
    assert "pool_weighting" not in plain["spec"] and not set(shared(plain)) & set(shared(first))


def test_a_study_says_whether_its_bracket_can_tell(client, study) -> None:
    """Per finished participant, from R: the matches that can tell (API and study page)."""
    empty = client.get(f"/api/studies/{study['id']}/power", headers=ADMIN)
    assert empty.status_code == 200 and empty.json() == []
    rewards = {
        c["id"]: c["env_reward"]
        for c in client.get(f"/api/studies/{study['id']}/candidates", headers=ADMIN).json()
    }
    person = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    label_bracket(
        client,
        person["token"],
        lambda m: min(  # against R every time it can
            (m["a"]["candidate_id"], m["b"]["candidate_id"]), key=rewards.__getitem__
        ),
    )
    power = client.get(f"/api/studies/{study['id']}/power?seeds=10", headers=ADMIN).json()
    assert len(power) == 1 and power[0]["participant_id"] == person["id"]
    row = power[0]
    assert row["n_matches"] == 7 and row["contested"] + row["uninformative"] == 7
    assert row["contested"] >= 5 and row["can_tell"] is False  # 7 matches: never 8
    assert row["min_detectable_delta"] is not None
    page = logged_in(client).get(f"/studies/{study['id']}")
    assert "Can this bracket tell?" in page.text and "this bracket cannot tell" in page.text
    assumed = f"It assumes that seeds' shares of contested matches kept spread by {SEED_SD:g}"
    assert assumed in " ".join(page.text.split())  # the experiment page's caveat, one home
    assert audit(page.text) == []
    for bad in ("1", "21", "x"):
        assert (
            client.get(f"/api/studies/{study['id']}/power?seeds={bad}", headers=ADMIN).status_code
            == 422
        )


def test_a_page_shows_a_judge_the_checkpoint_has(client, study) -> None:
    """A checkpoint judged before the return judge existed is shown by the first judge it has
    (the compare page's default), not refused."""
    experiment = _create(client, study_id=study["id"], teacher="good", seeds=2, **BODY)
    run_id = experiment["runs"][0]["id"]
    old = report_body(STEP, np.zeros(8)) | {"judges": {"value": {}, "behaviour": {}}}
    with client.app.state.runtime.sessions() as session:
        assert comparison.shown_judge(session, run_id=run_id, step=STEP) == "return"  # none yet
        artefacts.store(session, run_id=run_id, step=STEP, body=old)
        assert comparison.shown_judge(session, run_id=run_id, step=STEP) == "behaviour"
        new = report_body(2 * STEP, np.zeros(8)) | {"judges": {"return": {}, "behaviour": {}}}
        artefacts.store(session, run_id=run_id, step=2 * STEP, body=new)
        assert comparison.shown_judge(session, run_id=run_id, step=2 * STEP) == "return"
