"""Observation normaliser and reward scaler."""

from __future__ import annotations

import numpy as np

from engine.rl.normalize import ObsNormalizer, RewardScaler


def test_observations_end_up_standardised() -> None:
    rng = np.random.default_rng(0)
    norm = ObsNormalizer((3,))
    data = rng.normal([5.0, -2.0, 0.0], [10.0, 0.1, 1.0], size=(4000, 3))
    for chunk in np.split(data, 40):
        norm.update(chunk)
    out = norm(data)
    assert out.dtype == np.float32
    np.testing.assert_allclose(out.mean(0), 0.0, atol=0.05)
    np.testing.assert_allclose(out.std(0), 1.0, atol=0.05)


def test_state_dict_round_trip_gives_the_same_output() -> None:
    norm, copy = ObsNormalizer((2,)), ObsNormalizer((2,))
    norm.update(np.array([[1.0, 2.0], [3.0, 5.0]]))
    copy.load_state_dict(norm.state_dict())
    x = np.array([[0.5, 0.5]])
    np.testing.assert_array_equal(norm(x), copy(x))


def test_reward_scaler_tracks_the_discounted_return_and_resets_at_episode_end() -> None:
    scaler = RewardScaler(n_envs=2, gamma=0.5)
    scaler.update(np.array([1.0, 1.0]), np.array([False, True]))
    np.testing.assert_array_equal(scaler.returns, [1.0, 0.0])
    scaler.update(np.array([1.0, 1.0]), np.array([False, False]))
    np.testing.assert_array_equal(scaler.returns, [1.5, 1.0])
    scaled = scaler(np.array([2.0]))
    assert scaled[0] == 2.0 / np.sqrt(scaler.rms.var + 1e-8)


def test_disabled_normalisers_are_identities() -> None:
    x = np.array([[100.0, -3.0]])
    assert np.array_equal(ObsNormalizer((2,), enabled=False)(x), x.astype(np.float32))
    assert np.array_equal(RewardScaler(1, 0.9, enabled=False)(np.array([7.0])), [7.0])
