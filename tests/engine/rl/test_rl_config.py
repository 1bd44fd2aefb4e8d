"""TrainConfig: validation and JSON round trip."""

from __future__ import annotations

import json

import pytest

from engine.errors import InputError
from engine.rl.config import ALGOS, TrainConfig


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"algo": "dqn"}, "unknown algo"),
        ({"total_timesteps": -5}, "timesteps must be positive"),
        ({"total_timesteps": 0}, "timesteps must be positive"),
        ({"advice_scale": 0.0}, "advice-scale"),
        ({"advice_scale": float("inf")}, "advice-scale must be a positive finite number"),
        ({"advice_scale": float("nan")}, "advice-scale must be a positive finite number"),
        ({"advice_offset": -1.0}, "advice-offset"),
        ({"advice_offset": 101.0}, "advice-offset"),
        ({"checkpoint_every": 0}, "checkpoint-every"),
        ({"z_init": 3.0}, "z_init"),
        ({"num_minibatches": 10**9}, "num_minibatches"),
        ({"num_minibatches": 0}, "num_minibatches must be >= 1"),
        # 32 transitions in 32 minibatches: the std of one advantage is NaN
        (
            {"n_envs": 1, "num_steps": 32},
            r"leaves 1 per minibatch .* raise --n-envs or "
            r"--num-steps so that n-envs x num-steps >= 64",
        ),
        ({"seed": -1}, "seed must be in 0"),
        ({"seed": 2**64}, "seed must be in 0"),
        ({"advice_mode": "maximum"}, "unknown advice mode 'maximum'"),
        ({"advice_depth_factor": "depth"}, "unknown advice depth factor 'depth'"),
        ({"advice_kappa": 0.0}, "kappa must be a positive number"),
        ({"advice_kappa": float("nan")}, "kappa must be a positive number"),
    ],
)
def test_bad_values_raise_input_error(kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        TrainConfig(**kwargs)


@pytest.mark.parametrize("algo", ALGOS)
def test_json_round_trip(algo: str) -> None:
    cfg = TrainConfig(algo=algo, total_timesteps=1234, n_envs=2, num_steps=64)
    assert TrainConfig.from_json(cfg.to_json()) == cfg


def test_from_json_rejects_unknown_keys_and_non_objects() -> None:
    with pytest.raises(InputError, match="unknown config keys: bogus"):
        TrainConfig.from_json({**TrainConfig().to_json(), "bogus": 1})
    with pytest.raises(InputError):
        TrainConfig.from_json([1, 2])


def test_derived_sizes() -> None:
    cfg = TrainConfig(n_envs=4, num_steps=512, num_minibatches=32, total_timesteps=5000)
    assert (cfg.batch_size, cfg.minibatch_size, cfg.num_updates) == (2048, 64, 3)
    assert not cfg.uses_advice and TrainConfig(algo="bipars-em").learns_z


def test_smallest_valid_minibatch_is_two() -> None:
    assert TrainConfig(n_envs=1, num_steps=64, num_minibatches=32).minibatch_size == 2


def test_pool_weights_round_trip_as_a_list_and_are_left_out_when_unset() -> None:
    """JSON gives a list back; a config without weights is the dict it was before them (runs
    are reused by config)."""
    cfg = TrainConfig(algo="bipars-em", pool_weights=(1, 0.5, 0.0))
    assert cfg.pool_weights == (1.0, 0.5, 0.0)
    assert cfg.to_json()["pool_weights"] == [1.0, 0.5, 0.0]
    assert TrainConfig.from_json(json.loads(json.dumps(cfg.to_json()))) == cfg
    assert "pool_weights" not in TrainConfig().to_json()


@pytest.mark.parametrize(
    "weights",
    [[1.0], [0, 0], [1, -1], [1, float("nan")], [1, float("inf")], ["a", 1], [True, 1], "12"],
    ids=str,
)
def test_bad_pool_weights_raise_input_error(weights: object) -> None:
    with pytest.raises(InputError, match="pool weights must be"):
        TrainConfig(pool_weights=weights)  # type: ignore[arg-type]
