"""``acv validate``'s design and pre-registered analysis, without training: synthetic judge
statistics at advised and unadvised candidates, and synthetic CA tables (issue 27)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from engine.errors import InputError
from engine.pipeline import run_tournament
from engine.rl.behaviour import occupancy_scores
from engine.rl.reward_terms import CandidateTerms, term_scores
from engine.treefile import TreeDocument, dump_tree
from engine.validation import criteria, runs
from engine.validation.analysis import arm_table, judge_summary
from engine.validation.criteria import ArmData
from engine.validation.design import ARMS, PILOT, Plan
from engine.validation.figures import draw
from engine.validation.measure import JUDGES
from engine.validation.power import power
from engine.validation.runs import (
    arm_tasks,
    bracket_paths,
    finished,
    inverted,
    measures_path,
    pilot_tasks,
    prepare,
    run_dir,
    train_tasks,
)
from engine.validation.subsets import subset_outcomes, summary_subsets, table
from engine.validation.validate import report, status, steps_done
from engine.validation.workers import Workers
from engine.verdict import advice_scores

SEEDS, PILOTS = 5, 2  # 5: the exact one-sided test of ΔU reaches p = 1/32 < 0.05


@pytest.fixture(scope="module")
def advice() -> TreeDocument:
    return run_tournament(env_id="Hopper-v5", n_candidates=8, p=0.9, seed=1, teacher="orthogonal")


def _plan(arms: tuple[str, ...] = ("n1", "n2-1", "n2-10", "p1-10")) -> Plan:
    return Plan(
        env_id="Hopper-v5", teacher="orthogonal", timesteps=1000, seeds=SEEDS,
        pilot_seeds=PILOTS, brackets=1, candidates=8, arms=arms,
    )  # fmt: skip


def _statistic(judge: str, doc: TreeDocument, toward: np.ndarray, rng: np.random.Generator):
    """A judge's scores of an agent drawn to the candidates ``toward`` ranks high: the
    behaviour judge from synthetic visited states, the others from synthetic values."""
    order = np.argsort(-toward)
    if judge == "behaviour":
        near = np.array([doc.candidates[i].qpos for i in order[: len(order) // 2]])
        visited = np.repeat(near, 20, axis=0) + rng.normal(0, 1e-3, (20 * len(near), near.shape[1]))
        return list(occupancy_scores(visited, doc).values())
    values = toward + rng.normal(0, 1e-3, len(toward))
    zeros = np.zeros_like(values)
    terms = CandidateTerms(reward=zeros, advice=zeros, z=zeros, value=values)
    return list(term_scores(terms, "shaped-value", doc).values())


def _measures(judge: str, doc: TreeDocument, plan: Plan) -> dict:
    """Advised arms drawn to the advice's favourites, every other run to its least liked."""
    rng = np.random.default_rng(0)
    s = advice_scores(doc)
    runs = {(a, k) for a in plan.arms for k in range(SEEDS)} | {
        (PILOT.name, k) for k in plan.pilot_seed_list()
    }
    return {
        (arm, k): {
            "truth": float(arm.startswith("p1")) + rng.normal(0, 0.01),
            "scores": {judge: [_statistic(judge, doc, s if arm.startswith("p1") else -s, rng)]},
            "reward": [np.zeros(len(s)).tolist()],
        }
        for arm, k in runs
    }


@pytest.mark.parametrize("judge", ["return", "behaviour", "shaped-value"])
def test_advised_agents_are_told_apart_by_every_judge_statistic(
    judge: str, advice: TreeDocument
) -> None:
    plan = _plan()
    table = arm_table(_measures(judge, advice, plan), plan, judge, [advice])
    found = criteria.separation(table, np.random.default_rng(0), n_boot=200)
    assert found.value == 1.0 and found.low == 1.0 and found.passed
    assert (table["p1-10"].run_ca > table["n1"].run_ca.max()).all()


def test_the_summary_reports_every_criterion_and_what_it_could_not_compute(
    advice: TreeDocument, tmp_path: Path
) -> None:
    plan = _plan()
    summary = judge_summary(_measures("return", advice, plan), plan, "return", [advice])
    by_name = {c["name"]: c for c in summary["criteria"]}
    assert by_name["AUC p1-10 vs n1+n2"]["passed"] is True
    assert by_name["delta(n3)"]["passed"] is None
    assert "n3" in by_name["delta(n3)"]["note"]
    used = summary["verdicts"]["p1-10"]
    assert used["outcome"] == "used" and used["reason"] is None
    assert used["contested"] == used["informative"] >= 3  # the pilots reverse the advice
    assert summary["known"]["p1-10"] == "follows"
    assert summary["match_agreement_auc"]["value"] == 1.0
    whole = {"command": "acv validate", "commit": "abc", "plan": plan.to_json()}
    whole["judges"] = {"return": summary}
    whole["seed_subsets"] = summary_subsets(whole)
    (figure,) = draw(whole, tmp_path)
    assert Image.open(figure).size == (1300, 400)
    text = report(whole, [figure])
    assert "| return | delta(n3) | n/a |  | could not compute | arms not trained: n3 |" in text
    assert text.endswith("![return](figures/return.png)\n")
    assert "`acv validate` (commit `abc`)" in text
    assert "| return | p1-10 | 4 | 5 | 1.00 | 0.00 |" in text  # 4 of the 5 seeds, 5 ways


def _table(shifts: dict[str, float], seeds: int = 8, seed: int = 0) -> dict[str, ArmData]:
    rng = np.random.default_rng(seed)
    return {
        arm: ArmData(
            np.clip(0.3 + shift + rng.normal(0, 0.02, (seeds, 3)), 0, 1),
            shift + rng.normal(0, 0.01, seeds),
        )
        for arm, shift in shifts.items()
    }


def test_inverted_advice_is_seen_as_rejection_and_the_dose_as_a_dose() -> None:
    rng = np.random.default_rng(1)
    table = _table(
        {"n1": 0, "n2-1": 0, "n2-10": 0, "n3": -0.2, "p1-1": 0.1, "p1-3": 0.2, "p1-10": 0.4}
    )
    rejection = criteria.rejection(table, rng, n_boot=200)
    assert rejection.value is not None and rejection.value < 0 and rejection.passed
    dose = criteria.dose_response(table, rng, n_boot=200)
    assert dose.value is not None and dose.value > 0.8 and dose.passed
    pooled, within = criteria.truth_agreement(table)
    assert pooled.passed and set(within) == set(table) - {"n1"}


def test_no_effect_fails_the_separation_and_the_rejection() -> None:
    rng = np.random.default_rng(2)
    table = _table({"n1": 0, "n2-1": 0, "n2-10": 0, "n3": 0, "p1-10": 0})
    assert not criteria.separation(table, rng, n_boot=200).passed
    assert not criteria.rejection(table, rng, n_boot=200).passed


@pytest.mark.parametrize(
    ("delta_u", "expected"),
    [
        (np.full(8, 0.1) + np.linspace(0, 0.01, 8), "follows"),
        (-np.full(8, 0.1), "rejects"),
        (np.array([0.1, -0.1] * 4), "unknown"),
        (np.zeros(8), "unknown"),
        (np.array([0.1]), "unknown"),
        (np.full(4, 0.1), "unknown"),  # 4 seeds: the smallest one-sided p is 1/16
    ],
)
def test_known_direction_is_an_exact_one_sided_test(delta_u: np.ndarray, expected: str) -> None:
    assert criteria.known_direction(delta_u) == expected


def test_verdict_criteria_read_the_product_outcomes() -> None:
    assert criteria.no_false_use({"n2-1": "no-different", "n2-10": "cannot-tell"}).passed
    assert not criteria.no_false_use({"n2-1": "used", "n2-10": "no-different"}).passed
    assert criteria.no_false_use({"n2-1": "no-different"}).passed is None
    assert criteria.placebo(["no-different"] * 18 + ["used", "against"]).passed
    assert not criteria.placebo(["no-different"] * 17 + ["used"] * 3).passed
    follows = _table({"n1": 0, "p1-1": 0.3, "bipars-em": 0})
    assert criteria.hard_cases({"p1-1": "used"}, follows).passed
    assert not criteria.hard_cases({"p1-1": "no-different"}, follows).passed


def test_inverted_advice_reverses_every_match(advice: TreeDocument) -> None:
    flipped = inverted(advice)
    assert flipped.first_round == advice.first_round
    assert all(flipped.results[m] != w for m, w in advice.results.items() if m in flipped.results)
    scores = dict(advice.scores or {})
    scores.popitem()
    with pytest.raises(InputError, match="scores"):
        inverted(
            run_tournament(env_id="Hopper-v5", n_candidates=4, p=0.9, seed=0, teacher="random")
        )


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"seeds": 0}, "seeds must be at least 1"),
        ({"candidates": 2}, "candidates must be at least 4"),
        ({"arms": ("p1-10",)}, "must include n1"),
        ({"arms": ("n1",)}, "must include n1 and another arm"),
        ({"arms": ("n1", "p9")}, "unknown p9"),
        ({"teacher": "good"}, "posture score"),
        ({"seeds": 998}, "seeds \\+ n_envs must be at most 1000"),
    ],
)
def test_a_bad_plan_is_refused(change: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        Plan(**({"env_id": "Hopper-v5", "teacher": "orthogonal", "timesteps": 10} | change))


def test_arms_are_kept_in_one_order_whatever_order_they_are_given_in() -> None:
    assert _plan(("p1-10", "n1")).arms == ("n1", "p1-10") == _plan(("n1", "p1-10", "n1")).arms


def test_a_run_is_finished_at_its_last_whole_rollout(tmp_path: Path) -> None:
    """500k steps of 2,048 end at 501,760; a run with no checkpoint is not finished."""
    plan = _plan()
    folder = run_dir(tmp_path, "n1", 0)
    assert not finished(tmp_path, plan, ("n1", 0))
    (folder / "checkpoints").mkdir(parents=True)
    (folder / "checkpoints" / "step_512.pt").touch()
    assert not finished(tmp_path, plan, ("n1", 0))
    (folder / "checkpoints" / "step_1024.pt").touch()  # past the plan's 1000 steps
    assert finished(tmp_path, plan, ("n1", 0))


def test_the_baseline_trains_first_then_every_arm_seed_by_seed() -> None:
    tasks = arm_tasks(_plan())
    assert tasks[:SEEDS] == [("n1", seed) for seed in range(SEEDS)]
    assert tasks[SEEDS : SEEDS + 4] == [("n2-1", 0), ("n2-10", 0), ("p1-10", 0), ("n2-1", 1)]
    assert sorted(tasks) == sorted((a, s) for a in _plan().arms for s in range(SEEDS))


def test_a_measured_run_is_done_without_its_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The small files carry a validation to another machine: measures, not run folders."""
    plan, trained = _plan(), []
    monkeypatch.setattr(
        runs, "train_task", lambda out, plan, task, deadline=None: trained.append(task)
    )
    measures_path(tmp_path, ("n1", 0)).parent.mkdir(parents=True)
    measures_path(tmp_path, ("n1", 0)).write_text("{}")
    train_tasks(tmp_path, plan, [("n1", 0), ("n1", 1)], Workers())
    assert trained == [("n1", 1)]
    assert steps_done(tmp_path, plan, ("n1", 0)) == plan.timesteps
    assert steps_done(tmp_path, plan, ("n1", 1)) == 0


def test_the_status_says_what_is_measured_and_how_far_the_rest_trained(tmp_path: Path) -> None:
    plan = _plan(("n1", "p1-10"))
    measures_path(tmp_path, ("n1", 0)).parent.mkdir(parents=True)
    measures_path(tmp_path, ("n1", 0)).write_text("{}")
    folder = run_dir(tmp_path, "n1", 1)
    folder.mkdir(parents=True)
    (folder / "metrics.jsonl").write_text('{"timesteps": 512}\n')
    assert status(tmp_path, plan) == [
        "pilot: 0/2 measured",
        "n1: 1/5 measured (seeds 0); training seed 1 at 512 of 1,000 steps",
        "p1-10: 0/5 measured",
    ]


def test_the_status_counts_what_each_judge_can_tell_once_the_pilots_are_measured(
    tmp_path: Path, advice: TreeDocument
) -> None:
    """Pilots that reverse every preference of the advice contest every informative match."""
    plan = _plan(("n1", "p1-10"))
    path = bracket_paths(tmp_path, plan)[0]
    path.parent.mkdir(parents=True)
    dump_tree(advice, path)
    assert len(status(tmp_path, plan)) == 3  # the arms only: no pilot is measured yet
    reversed_ = {judge: [(-advice_scores(advice)).tolist()] for judge in JUDGES}
    for task in pilot_tasks(plan):
        measures_path(tmp_path, task).parent.mkdir(parents=True, exist_ok=True)
        measures_path(tmp_path, task).write_text(json.dumps({"scores": reversed_}))
    counts = status(tmp_path, plan)[3:]
    assert [line.split(":")[0] for line in counts] == list(JUDGES)
    for line in counts:  # bracket 0: n informative, n contested; the 1 brackets: n and n
        numbers = [int(x) for x in re.findall(r"\d+", line)]
        n = numbers[1]
        assert numbers == [0, n, n, 1, n, n] and n >= 3, line


@pytest.mark.parametrize("text", ["not json", '{"env_id": "Hopper-v5"}', '{"timesteps": "x"}'])
def test_a_folder_with_a_broken_plan_file_is_refused(tmp_path: Path, text: str) -> None:
    (tmp_path / "validate.json").write_text(text)
    with pytest.raises(InputError, match="does not hold a validation's settings"):
        prepare(tmp_path, _plan())


def test_a_folder_holds_one_plan(tmp_path: Path) -> None:
    prepare(tmp_path, _plan())
    prepare(tmp_path, _plan())  # the same plan resumes
    assert json.loads((tmp_path / "validate.json").read_text())["arms"] == list(_plan().arms)
    with pytest.raises(InputError, match="arms"):
        prepare(tmp_path, _plan(("n1",)))


def test_the_power_simulation_separates_an_effect_from_none() -> None:
    rng = np.random.default_rng(0)
    none = power(0.0, seeds=8, brackets=3, rng=rng, simulations=5, n_boot=50)
    large = power(0.5, seeds=8, brackets=3, rng=rng, simulations=5, n_boot=50)
    assert none["AUC p1-10 vs n1+n2"] == 0.0 and large["AUC p1-10 vs n1+n2"] == 1.0
    assert set(none) == set(large) and len(none) == 7
    assert {a.name for a in ARMS} >= {"n1", "p1-10"}


@pytest.mark.parametrize(
    ("advised", "k", "used", "against"),
    [
        (1.0, 4, 1.0, 0.0),  # every advised seed above every baseline seed: p = 2/70
        (0.0, 4, 0.0, 1.0),  # and below
        (1.0, 3, 0.0, 0.0),  # 3 against 3 never reaches p = 0.05
    ],
)
def test_fewer_seeds_say_what_the_exact_test_allows(
    advised: float, k: int, used: float, against: float
) -> None:
    found = subset_outcomes(
        np.full(8, advised), np.full(8, 1 - advised), k, np.random.default_rng(0)
    )
    assert (found["subsets"], found["used"], found["against"]) == (math.comb(8, k), used, against)


def test_fewer_seeds_fire_at_most_alpha_under_the_null() -> None:
    """Both arms from one distribution: each subset's exact test rejects at most 5% of the
    time, so the mean share of subsets saying either outcome is at most about 0.05."""
    rng = np.random.default_rng(1)
    fired = []
    for _ in range(300):
        found = subset_outcomes(rng.uniform(size=8), rng.uniform(size=8), 4, rng)
        fired.append(found["used"] + found["against"])
    assert np.mean(fired) <= 0.05 + 0.015


def test_a_summary_is_read_on_the_advice_bracket() -> None:
    """Bracket 0 is the advice's: the other brackets' CA never enter; an arm with no
    contested match there (NaN), or too few for the verdict to count, is left out."""
    ca = {"n1": [[0.0, 1.0]] * 8, "p1-10": [[1.0, 0.0]] * 8, "n3": [[None, 0.0]] * 8}
    ca["p1-1"] = ca["p1-10"]
    verdicts = {"p1-1": {"contested": 2}, "p1-10": {"contested": 3}}
    found = summary_subsets({"judges": {"behaviour": {"ca": ca, "verdicts": verdicts}}})
    found = found["behaviour"]
    assert set(found) == {"p1-10"}
    assert [(r["k"], r["used"]) for r in found["p1-10"]] == [(4, 1.0), (5, 1.0), (8, 1.0)]
    assert "| behaviour | p1-10 | 4 | 70 | 1.00 | 0.00 |" in table({"behaviour": found})
