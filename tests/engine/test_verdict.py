"""The verdict against a matched no-advice baseline (issue 25 §3-4), on synthetic judges whose
truth is known: each run's judge scores a candidate by a latent preference that every agent
shares, plus ``shift`` times the advice (the advice's pull on advised runs), plus seed noise."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from engine.disagreement import disagreement_pairs
from engine.errors import InputError
from engine.verdict import (
    Pair,
    Verdict,
    VerdictInputs,
    VerdictOptions,
    advice_scores,
    bracket_pairs,
    classify,
    split_matches,
)
from engine.verdict_outcome import verdict
from tests.support.candidates import r_judged_doc

N = 16
#: seed noise against a latent preference of spread 1: seeds disagree often, as real judges do
NOISY = 4.0
FAST = VerdictOptions(n_boot=50)  # the interval never decides: the simulations skip most of it


def _bracket(advice: np.ndarray) -> tuple[Pair, ...]:
    """A 16-player single-elimination bracket played by the advice's scores."""
    players, pairs = list(range(len(advice))), []
    while len(players) > 1:
        winners = []
        for a, b in zip(players[::2], players[1::2], strict=True):
            w = a if advice[a] > advice[b] else b
            pairs.append((a, b, w))
            winners.append(w)
        players = winners
    return tuple(pairs)


def _inputs(
    rng: np.random.Generator,
    *,
    shift: float = 0.0,
    k: int = 5,
    k_pilot: int = 3,
    noise: float = 1.0,
    circular: bool = False,
    pairs: int = 0,
    pairs_circular: bool = False,
) -> VerdictInputs:
    """Synthetic judges: advised runs are pulled ``shift`` toward the advice; the pilot runs
    are fresh no-advice seeds, or the evaluation baseline itself when ``circular``. With
    ``pairs``, the bracket is followed by that many disagreement pairs, answered as the advice
    prefers, picked with a study baseline of its own (a fresh no-advice seed), or with the
    evaluation baseline's mean when ``pairs_circular``."""
    advice, latent = rng.normal(size=N), rng.normal(size=N)

    def runs(n: int, pull: float = 0.0) -> np.ndarray:
        return latent + pull * advice + noise * rng.normal(size=(n, N))

    baseline, bracket = runs(k), _bracket(advice)
    asked: list[tuple[int, int]] = []
    if pairs:  # draws nothing more otherwise: the other tests keep their random designs
        study_baseline = baseline.mean(axis=0) if pairs_circular else runs(1)[0]
        played = [(a, b) for a, b, _ in bracket]
        asked = disagreement_pairs(advice, study_baseline, k=pairs, played=played)
    return VerdictInputs(
        advice=advice,
        advised=runs(k, shift),
        baseline=baseline,
        pilot=baseline if circular else runs(k_pilot),
        matches=bracket + tuple((a, b, a) for a, b in asked),
    )


def _simulate(n: int, seed: int, **kwargs: object) -> tuple[np.ndarray, np.ndarray]:
    """Outcomes and Δs (NaN where none) of ``n`` independent synthetic designs."""
    rng = np.random.default_rng(seed)
    verdicts = [verdict(_inputs(rng, **kwargs), rng, FAST) for _ in range(n)]  # type: ignore[arg-type]
    outcomes = np.array([v.outcome for v in verdicts])
    deltas = np.array([np.nan if v.delta is None else v.delta for v in verdicts])
    return outcomes, deltas


def test_false_positives_stay_at_alpha_when_pilot_seeds_pick_the_matches() -> None:
    outcomes, deltas = _simulate(1000, seed=1, noise=NOISY)
    fired = np.isin(outcomes, ["used", "against"]).mean()
    assert fired <= 0.065
    assert abs(np.nanmean(deltas)) < 0.02  # no bias: same distribution, Δ about 0
    assert (outcomes == "no-different").mean() > 0.5  # the designs mostly could tell


def test_disagreement_pairs_from_a_baseline_of_their_own_keep_false_positives_at_alpha() -> None:
    """Pairs picked by the study's baseline (never an evaluation run) add contested matches
    without biasing Δ; picked by the evaluation baseline, they would."""
    rng = np.random.default_rng(3)
    with_pairs = [classify(_inputs(rng, noise=NOISY, pairs=10)) for _ in range(200)]
    bracket_only = [classify(_inputs(rng, noise=NOISY)) for _ in range(200)]
    assert np.mean([len(c.contested) for c in with_pairs]) > 1.5 * np.mean(
        [len(c.contested) for c in bracket_only]
    )
    outcomes, deltas = _simulate(1000, seed=4, noise=NOISY, pairs=10)
    assert np.isin(outcomes, ["used", "against"]).mean() <= 0.065
    assert abs(np.nanmean(deltas)) < 0.02
    _, circular = _simulate(300, seed=4, noise=NOISY, pairs=10, pairs_circular=True)
    assert np.nanmean(circular) > 0.03  # the evaluation baseline loses the pairs chosen on it


def test_picking_the_matches_on_the_evaluation_seeds_biases_every_delta_up() -> None:
    outcomes, deltas = _simulate(1000, seed=1, noise=NOISY, circular=True)
    assert np.nanmean(deltas) > 0.1  # the baseline loses what it was chosen to lose
    assert (outcomes == "used").mean() > 0.08  # the false-positive bound above fails


def test_advised_agents_pulled_toward_the_advice_used_it() -> None:
    outcomes, deltas = _simulate(50, seed=2, shift=8.0, noise=NOISY)
    assert (outcomes == "used").mean() > 0.5 and np.nanmean(deltas) > 0.3
    assert "against" not in outcomes


def test_advised_agents_pushed_away_from_the_advice_went_against_it() -> None:
    # the noisy baseline keeps some contested matches by chance, so there is room below it
    outcomes, deltas = _simulate(50, seed=3, shift=-8.0, noise=NOISY)
    assert (outcomes == "against").mean() > 0.5 and np.nanmean(deltas) < -0.3
    assert "used" not in outcomes


def test_verdict_sentence_names_the_numbers() -> None:
    rng = np.random.default_rng(4)
    v = verdict(_inputs(rng, shift=3.0), rng)
    assert v.outcome == "used" and v.text.startswith(
        f"On {len(v.matches.contested)} matches where your advice and an agent without it disagree"
    )
    assert "(5 seeds)" in v.text and ": used your advice." in v.text and "Δ ≥" in v.text
    assert v.interval is not None and v.delta is not None
    assert v.interval[0] <= v.delta <= v.interval[1]
    assert v.p_value == pytest.approx(2 / 252) and v.auc == 1.0


def _two_contested() -> VerdictInputs:
    """Four matches: two contested, one agreed, one where the advice barely prefers."""
    advice = np.array([1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.999])
    pilot = np.array([[0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0]])
    pairs = ((0, 1, 0), (2, 3, 2), (4, 5, 4), (6, 7, 6))
    runs = np.tile(advice, (5, 1))
    return VerdictInputs(advice, runs, runs[:, ::-1], pilot, pairs)


def test_two_informative_contested_matches_cannot_tell() -> None:
    inputs = _two_contested()
    classes = classify(inputs)
    assert classes.contested == ((0, 1, 0), (2, 3, 2))
    assert classes.agreed == ((4, 5, 4),) and classes.uninformative == ((6, 7, 6),)
    v = verdict(inputs, np.random.default_rng(0))
    assert v.outcome == "cannot-tell" and "only 2 informative contested matches" in (v.reason or "")
    assert v.delta == 1.0  # reported, but it decides nothing


def test_margins_are_shares_of_the_score_spread() -> None:
    inputs = _two_contested()
    assert len(classify(inputs, VerdictOptions(margin_advice=0.0)).uninformative) == 0
    assert len(classify(inputs, VerdictOptions(margin_baseline=1.01)).uninformative) == 4


def test_three_seeds_against_three_cannot_tell() -> None:
    rng = np.random.default_rng(5)
    v = verdict(_inputs(rng, shift=5.0, k=3), rng)
    assert v.outcome == "cannot-tell" and "never goes below p = 0.1" in (v.reason or "")
    assert v.min_detectable_delta is None and "cannot detect any Δ" in v.text


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"pilot": "advice"}, "only 0 informative contested matches"),
        ({"advice": "flat"}, "only 0 informative contested matches"),
        ({"advised": "flat", "baseline": "flat"}, "ties every contested match"),
        ({"advised": "one"}, "with 1 seed against 5"),
        ({"advised": "none"}, "no advised runs"),
        ({"pilot": "none"}, "no pilot baseline runs"),
    ],
)
def test_edge_cases_cannot_tell_with_a_reason(change: dict[str, str], reason: str) -> None:
    rng = np.random.default_rng(6)
    base = _inputs(rng, shift=2.0)
    fields = {
        "advice": base.advice,
        "advised": base.advised,
        "baseline": base.baseline,
        "pilot": base.pilot,
        "matches": base.matches,
    }
    values = {
        "advice": base.advice[None],
        "flat": np.zeros((5, N)),
        "one": base.advised[:1],
        "none": np.zeros((0, N)),
    }
    for name, how in change.items():
        fields[name] = np.zeros(N) if (name, how) == ("advice", "flat") else values[how]
    v = verdict(VerdictInputs(**fields), rng)  # type: ignore[arg-type]
    assert v.outcome == "cannot-tell" and reason in (v.reason or "")
    assert v.text.endswith("with power 0.8.") and json.dumps(v.to_json())


def test_immediate_r_contested_is_reported_beside_from_the_r_passed_in() -> None:
    inputs = _two_contested()
    reward = np.array([0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0])  # a tie in 2-3: not contested
    with_r = VerdictInputs(**{**inputs.__dict__, "reward": reward})
    classes = classify(with_r)
    assert classes.r_contested == ((0, 1, 0), (4, 5, 4))  # informative only
    assert classify(inputs).r_contested == ()


def test_to_json_lists_the_matches_and_numbers() -> None:
    rng = np.random.default_rng(7)
    obj = verdict(_inputs(rng, shift=3.0), rng).to_json()
    assert set(obj["matches"]) == {"contested", "agreed", "uninformative", "r_contested"}
    assert obj["n_contested"] == len(obj["matches"]["contested"])
    assert isinstance(obj["interval"], list) and len(obj["ca_advised"]) == 5
    assert json.loads(json.dumps(obj)) == obj
    assert Verdict.from_json(json.loads(json.dumps(obj))).to_json() == obj


@pytest.mark.parametrize(
    "bad",
    [
        {"advice": np.zeros(1)},
        {"advised": np.zeros((5, N + 1))},
        {"pilot": np.zeros(N)},
        {"matches": ((0, 1, 2),)},
        {"matches": ((0, N, 0),)},
        {"reward": np.zeros(3)},
    ],
)
def test_bad_inputs_are_input_errors(bad: dict[str, object]) -> None:
    fields = {
        "advice": np.zeros(N),
        "advised": np.zeros((5, N)),
        "baseline": np.zeros((5, N)),
        "pilot": np.zeros((3, N)),
        "matches": ((0, 1, 0),),
        **bad,
    }
    with pytest.raises(InputError):
        VerdictInputs(**fields)  # type: ignore[arg-type]


def test_advice_scores_are_the_trees_scores_else_its_heights() -> None:
    doc = r_judged_doc()
    assert advice_scores(doc).tolist() == [doc.scores[c.id] for c in doc.candidates]
    heights = advice_scores(dataclasses.replace(doc, scores=None))
    assert heights.tolist() == [doc.tree.nodes[c.id].height for c in doc.candidates]
    pairs = bracket_pairs(doc)
    assert len(pairs) == len(doc.candidates) - 1
    assert all(heights[w] >= heights[b if w == a else a] + 1 for a, b, w in pairs)


def test_before_any_baseline_r_estimates_the_matches_that_can_tell() -> None:
    doc = r_judged_doc()  # judged by R itself: an R-only agent contests nothing
    r = np.array([c.env_reward for c in doc.candidates])
    classes = split_matches(advice_scores(doc), r, bracket_pairs(doc))
    assert classes.contested == () and len(classes.agreed) == len(doc.matches)
    reversed_r = split_matches(advice_scores(doc), -r, bracket_pairs(doc), reward=r)
    assert len(reversed_r.contested) == len(doc.matches) and reversed_r.r_contested == ()
