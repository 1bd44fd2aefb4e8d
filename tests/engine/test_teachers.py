"""Simulated teachers and flip noise."""

from __future__ import annotations

import numpy as np
import pytest

from engine.envs import env_model
from engine.errors import InputError
from engine.teachers import make_teacher
from tests.support.candidates import make_candidates


@pytest.fixture
def model():
    return env_model("Hopper-v5")


def test_good_teacher_prefers_higher_reward(model) -> None:
    a, b = make_candidates(2)
    judge, scores = make_teacher("good", [a, b], model, rng=np.random.default_rng(0))
    best = a if a.env_reward > b.env_reward else b
    assert judge(a, b) == judge(b, a) == best.id
    assert scores == {a.id: a.env_reward, b.id: b.env_reward}


def test_full_noise_always_flips(model) -> None:
    a, b = make_candidates(2)
    clean, _ = make_teacher("good", [a, b], model, rng=np.random.default_rng(0))
    noisy, _ = make_teacher("good", [a, b], model, noise=1.0, rng=np.random.default_rng(0))
    assert all(noisy(a, b) != clean(a, b) for _ in range(20))


@pytest.mark.parametrize("noise", [0.1, 0.3])
def test_noise_flips_at_its_rate(model, noise: float) -> None:
    a, b = make_candidates(2)
    judge, _ = make_teacher("standing", [a, b], model, noise=noise, rng=np.random.default_rng(1))
    clean, _ = make_teacher("standing", [a, b], model, rng=np.random.default_rng(1))
    flips = np.mean([judge(a, b) != clean(a, b) for _ in range(4000)])
    assert flips == pytest.approx(noise, abs=0.03)


def test_random_teacher_is_a_fair_coin(model) -> None:
    a, b = make_candidates(2)
    judge, scores = make_teacher("random", [a, b], model, rng=np.random.default_rng(2))
    assert scores is None
    assert np.mean([judge(a, b) == a.id for _ in range(4000)]) == pytest.approx(0.5, abs=0.03)


@pytest.mark.parametrize(("name", "noise"), [("expert", 0.0), ("good", 1.5), ("good", -0.1)])
def test_bad_teacher_arguments(model, name: str, noise: float) -> None:
    with pytest.raises(InputError):
        make_teacher(name, make_candidates(2), model, noise=noise, rng=np.random.default_rng(0))
