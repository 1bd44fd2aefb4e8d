"""``acv survey create|add-respondents|results|export`` on SQLite and PostgreSQL."""

from __future__ import annotations

import csv
import io
import json
import re

import pytest
from typer.testing import CliRunner

from app.cli import cli
from tests.support.surveys import Respondent, finished, paper_answers, tree_json


@pytest.fixture
def run(monkeypatch, backend_url):
    """Invoke ``acv`` in-process on this module's database."""
    data_dir, url = backend_url
    monkeypatch.setenv("ACV_DATA_DIR", str(data_dir))
    monkeypatch.setenv("DATABASE_URL", url)
    runner = CliRunner()
    return lambda *args: runner.invoke(cli, list(args))


def test_create_invite_answer_results_export(run, client, study, tmp_path) -> None:
    human = finished(client, study["id"], "a")
    upload = tree_json(client, finished(client, study["id"], "b"))
    spec = tmp_path / "survey.json"
    spec.write_text(
        json.dumps(
            {
                "name": "CLI survey",
                "paper_terms": {"tree1": "standing", "tree2": "crouching"},
                "stimuli": [
                    {
                        "tree1": {"kind": "participant", "participant_id": human},
                        "tree2": {"kind": "upload", "doc": upload, "study_id": study["id"]},
                    }
                ],
            }
        )
    )
    created = run("survey", "create", "--spec", str(spec))
    assert created.exit_code == 0, created.output
    survey_id = re.search(
        r"survey (\d+) open: 1 stimuli, exclusion rule: no exclusions", created.output
    )[1]
    added = run("survey", "add-respondents", "--survey", survey_id, "--count", "2")
    links = re.findall(r"^(\d+)\thttp://127\.0\.0\.1:8000/r/(\S{43})$", added.output, re.M)
    assert added.exit_code == 0 and len(links) == 2
    person = Respondent(client, int(links[0][0]), links[0][1], "")
    screen = person.screen()
    assert (
        screen["questions"][1]["text"] == "Tree 1 prefers standing. Does Tree 2 prefer crouching?"
    )
    assert person.answer(1, paper_answers(screen, q2="no"), screen_ms=1500).status_code == 201

    results = run("survey", "results", "--survey", survey_id, "--json")
    assert results.exit_code == 0, results.output
    body = json.loads(results.output)
    assert body["respondents"]["finished"] == 1
    q1, q2 = body["without_exclusions"]
    assert (q1["accuracy"]["k"], q2["accuracy"]["k"], q2["counts"]) == (1, 0, {"yes": 0, "no": 1})
    assert body["with_exclusions"] == body["without_exclusions"]
    text = run("survey", "results", "--survey", survey_id)
    assert "q2: n = 1, 0/1 as expected" in text.output and "paper q2: 17/20" in text.output

    out = tmp_path / "answers.csv"
    assert run("survey", "export", "--survey", survey_id, "--out", str(out)).exit_code == 0
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert [(r["question"], r["value"], r["screen_ms"]) for r in rows] == [
        ("q1", "different", "1500"),
        ("q2", "no", "1500"),
    ]
    lines = tmp_path / "answers.jsonl"
    assert (
        run(
            "survey", "export", "--survey", survey_id, "--out", str(lines), "--format", "jsonl"
        ).exit_code
        == 0
    )
    assert [json.loads(x)["question"] for x in lines.read_text().splitlines()] == ["q1", "q2"]


@pytest.mark.parametrize(
    ("args", "spec", "message"),
    [
        (["survey", "results", "--survey", "424242"], None, "survey 424242 not found"),
        (["survey", "add-respondents", "--survey", "424242"], None, "survey 424242 not found"),
        (["survey", "create"], {"name": "x", "stimuli": []}, "stimuli: List should have at least"),
        (["survey", "create"], {"name": "x", "seed": True, "stimuli": [{}]}, "seed"),
        (
            ["survey", "create"],
            {
                "name": "x",
                "stimuli": [
                    {
                        "tree1": {"kind": "participant", "participant_id": 424242},
                        "tree2": {"kind": "participant", "participant_id": 424242},
                    }
                ],
            },
            "participant 424242 not found",
        ),
    ],
)
def test_bad_input_is_one_line_and_exit_2(run, tmp_path, args, spec, message) -> None:
    if spec is not None:
        path = tmp_path / "spec.json"
        path.write_text(json.dumps(spec))
        args = [*args, "--spec", str(path)]
    result = run(*args)
    assert result.exit_code == 2, result.output
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1
