"""§6.8's H1 (the baseline's spread), on fabricated ``n1`` measures whose r are set exactly."""

from __future__ import annotations

import json
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from engine.treefile import dump_tree, load_tree
from engine.validation.round2 import EVAL_SEED0
from engine.validation.round2_analysis import SCORES
from engine.validation.round2_runs import PLAN_FILE, Round2Plan, measures_path
from engine.validation.round2_spread import baseline_spread, main, supported, variance_test
from engine.verdict_bracket import tree_values

ROUND1 = Path(__file__).parents[2] / "docs/validation/humanoid-orthogonal/brackets"
PLAN = Round2Plan(env_id="Hopper-v5", timesteps=500_000)


def _with_r(values: np.ndarray, r: float, rng: np.random.Generator) -> np.ndarray:
    """Scores whose Pearson r with ``values`` is exactly ``r``."""
    z = (values - values.mean()) / values.std()
    other = rng.normal(size=values.shape)
    other -= other.mean() + (other @ z) / (z @ z) * z  # centred, orthogonal to z
    return r * z + np.sqrt(1 - r**2) * other / other.std()


def _round(folder: Path, r_per_seed: list[float]) -> Path:
    """Round 2's folder with its advice trees and ``n1``'s measures, each seed at its r."""
    (folder / "advice").mkdir(parents=True)
    (folder / PLAN_FILE).write_text(json.dumps(asdict(PLAN)))
    rng = np.random.default_rng(3)
    values = {}
    for b in range(PLAN.brackets):
        advice = replace(load_tree(ROUND1 / f"bracket_{b}.json"), scores=None)
        for kind in ("advice", "shuffled"):
            dump_tree(advice, folder / "advice" / f"{kind}-b{b}.json")
        values[f"b{b}"] = tree_values(advice)
    for k, r in enumerate(r_per_seed):
        scores = {
            name: {s: _with_r(v, r, rng).tolist() for s in SCORES} for name, v in values.items()
        }
        path = measures_path(folder, ("n1", EVAL_SEED0 + k))
        path.parent.mkdir(exist_ok=True)
        path.write_text(json.dumps({"scores": scores, "truth": {"orthogonal": 0.3}}))
    return folder


@pytest.mark.parametrize(("sd", "wider"), [(0.1, False), (0.2, False), (0.5, True)])
def test_the_variance_test_rejects_only_a_wider_spread(sd: float, wider: bool) -> None:
    r = np.array([-1.0, 1.0] * 5) * sd * np.sqrt(9 / 10)  # sample sd exactly ``sd``
    found_sd, p = variance_test(r)
    assert found_sd == pytest.approx(sd)
    assert p == pytest.approx(stats.chi2.sf(9 * sd**2 / 0.04, df=9))
    assert (p < 0.05) is wider


def test_under_the_null_the_variance_test_fires_at_its_level() -> None:
    """10 seeds drawn at the assumed spread: "wider" in 5% ± 1.5% of 2,000 draws."""
    draws = np.random.default_rng(0).normal(0.0, 0.2, size=(2000, 10))
    fired = np.mean([variance_test(r)[1] < 0.05 for r in draws])
    assert 0.035 <= fired <= 0.065


def test_a_split_baseline_supports_h1(tmp_path: Path) -> None:
    r = [-0.4, -0.3, 0.7, 0.75, -0.35, 0.7, -0.3, 0.2, 0.55, 0.75]  # as Hopper-v5's
    spreads = baseline_spread(_round(tmp_path, r))
    assert [s.bracket for s in spreads] == ["b0", "b1", "b2"]
    assert spreads[0].r == pytest.approx(r)
    assert spreads[0].sd == pytest.approx(np.std(r, ddof=1))
    assert all(s.wider for s in spreads) and supported(spreads)


def test_a_baseline_as_assumed_does_not(tmp_path: Path) -> None:
    r = list(np.linspace(-0.25, 0.25, 10))  # sd 0.18
    spreads = baseline_spread(_round(tmp_path, r))
    assert not any(s.wider for s in spreads) and not supported(spreads)


def test_the_command_prints_the_reading_or_names_what_is_missing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _round(tmp_path, [-0.5, 0.6] * 5)
    main([str(folder)])
    assert json.loads(capsys.readouterr().out)["supported"] is True
    measures_path(folder, ("n1", EVAL_SEED0 + 3)).unlink()
    with pytest.raises(SystemExit) as exited:
        main([str(folder)])
    assert exited.value.code == 2
    assert "not measured yet: n1-103" in capsys.readouterr().err
