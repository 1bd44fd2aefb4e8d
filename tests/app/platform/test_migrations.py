"""The schema comes from Alembic: it matches the models, and migrates down and up again."""

from __future__ import annotations

from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import inspect, text

from app.db import downgrade, make_engine, upgrade
from app.models import Base
from tests.support.runs import run_app
from tests.support.studies import new_study
from tests.support.surveys import invite, paper_answers, paper_body, participant_trees
from tests.support.web import ADMIN

TABLES = set(Base.metadata.tables)


def _tables(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return set(inspect(engine).get_table_names()) - {"alembic_version"}
    finally:
        engine.dispose()


def test_the_web_app_tables_are_models() -> None:
    web_app = {"studies", "candidates", "bracket_slots", "participants", "matches", "labels"}
    assert web_app <= TABLES


def test_migrated_schema_matches_the_models(backend_url) -> None:
    engine = make_engine(backend_url[1])
    try:
        with engine.connect() as conn:
            diff = compare_metadata(
                MigrationContext.configure(conn, opts={"compare_type": True}), Base.metadata
            )
    finally:
        engine.dispose()
    assert diff == []


def test_downgrade_and_upgrade_again(backend_url) -> None:
    url = backend_url[1]
    assert _tables(url) == TABLES
    downgrade(url, "base")
    assert _tables(url) == set()
    upgrade(url)
    assert _tables(url) == TABLES


def test_labels_match_id_is_unique_in_the_schema(backend_url) -> None:
    engine = make_engine(backend_url[1])
    try:
        uniques = inspect(engine).get_unique_constraints("labels")
    finally:
        engine.dispose()
    assert [u["column_names"] for u in uniques] == [["match_id"]]


def test_sqlite_runs_in_wal_mode_with_foreign_keys(tmp_path) -> None:
    url = f"sqlite:///{tmp_path / 'x.sqlite3'}"
    upgrade(url)
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            assert conn.execute(text("PRAGMA journal_mode")).scalar() == "wal"
            assert conn.execute(text("PRAGMA foreign_keys")).scalar() == 1
    finally:
        engine.dispose()


_PEOPLE = ("participants", "labels", "survey_respondents", "survey_answers", "runs")


def _counts(url: str) -> dict[str, int]:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return {
                t: conn.execute(text(f"SELECT count(*) FROM {t}")).scalar_one() for t in _PEOPLE
            }
    finally:
        engine.dispose()


def test_the_run_state_revision_keeps_every_row(settings) -> None:
    """A database filled at the previous head (0012) keeps every participant, label,
    respondent, answer and run through ``upgrade head`` (0013 adds the run state tables)."""
    with run_app(settings, worker=False) as client:
        study = new_study(client)
        trees = participant_trees(client, study["id"])
        survey = client.post("/api/surveys", json=paper_body(*trees), headers=ADMIN).json()
        [respondent] = invite(client, survey["id"])
        while (screen := respondent.screen()) is not None:
            assert respondent.answer(screen["position"], paper_answers(screen)).status_code == 201
        body = {"study_id": study["id"], "algo": "ppo", "timesteps": 1000}
        assert client.post("/api/runs", json=body, headers=ADMIN).status_code == 202
    url = settings.sqlalchemy_url
    downgrade(url, "0012")  # as it was filled at the previous head
    before = _counts(url)
    assert all(before.values()), before
    upgrade(url)
    assert _counts(url) == before
    assert {"run_metrics", "run_checkpoints"} <= _tables(url)


def _limits_state(url: str) -> tuple[dict, dict]:
    """``({study id: (webhook_count, gold_item_count)}, {run id: config_digest})``."""
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            counts = conn.execute(text("SELECT id, webhook_count, gold_item_count FROM studies"))
            shared = conn.execute(
                text("SELECT id, config_digest FROM runs WHERE config_digest IS NOT NULL")
            )
            return {i: (w, g) for i, w, g in counts}, dict(shared.all())
    finally:
        engine.dispose()


def test_the_limits_revision_backfills_counters_and_shared_runs(settings) -> None:
    """0016 counts each study's webhooks and gold items, and marks the runs experiments
    shared (the oldest ``ppo`` run naming advice per study, config and seed), from the rows
    alone: after a downgrade to 0015 and back, both are as the app kept them."""
    with run_app(settings, worker=False) as client:
        study = new_study(client, n_candidates=4, seed=16)
        for i in range(3):
            hook = {"url": f"http://127.0.0.1:9/{i}", "study_id": study["id"]}
            assert client.post("/api/webhooks", json=hook, headers=ADMIN).status_code == 201
        gold = {"kind": "pair", "a": 0, "b": 1, "answer": 1}
        for _ in range(2):
            added = client.post(f"/api/studies/{study['id']}/gold", json=gold, headers=ADMIN)
            assert added.status_code == 201
        body = {"study_id": study["id"], "teacher": "good", "timesteps": 512, "n_envs": 1}
        experiment = {**body, "algo": "bipars-em", "seeds": 2, "pilot_seeds": 1}
        assert client.post("/api/experiments", json=experiment, headers=ADMIN).status_code == 202
        again = {**body, "algo": "ppo", "seed": 0}  # the baseline's twin: not the shared one
        assert client.post("/api/runs", json=again, headers=ADMIN).status_code == 202
    url = settings.sqlalchemy_url
    counts, shared = _limits_state(url)
    assert counts[study["id"]] == (3, 2) and len(shared) >= 3
    downgrade(url, "0015")
    upgrade(url)
    assert _limits_state(url) == (counts, shared)
