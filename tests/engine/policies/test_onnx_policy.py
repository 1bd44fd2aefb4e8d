"""An imported policy in the judges' hands: :class:`OnnxPolicy` computes the MLP's mean on one
thread, its normalisation is read from an ``.npz`` without pickle and applied as SB3 and ACV
apply theirs, and what fails at run time is an :class:`InputError`."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest
from onnx import helper

from engine.errors import InputError
from engine.policies.normalisation import MAX_NPZ_BYTES, ObsNormalisation
from engine.policies.onnx_build import mlp_onnx
from engine.policies.onnx_check import CheckedOnnx, check_onnx
from engine.policies.onnx_policy import ImportedPolicy, OnnxPolicy
from engine.rl.normalize import ObsNormalizer
from tests.support.onnx_models import (
    ACT_DIM,
    ENV,
    OBS_DIM,
    linear_graph,
    mlp_bytes,
    numpy_mean,
    random_layers,
)
from tests.support.zips import BREAKS, broken_first_member


def checked(data: bytes) -> CheckedOnnx:
    return check_onnx(data, env_id=ENV, obs_dim=OBS_DIM, act_dim=ACT_DIM)


def normalisation(seed: int = 1) -> ObsNormalisation:
    rng = np.random.default_rng(seed)
    return ObsNormalisation(rng.normal(size=OBS_DIM), rng.uniform(0.1, 4, OBS_DIM), 5.0, 1e-8)


@pytest.mark.parametrize("activation", ["tanh", "relu"])
def test_the_policy_computes_the_mlp_mean(activation: str) -> None:
    layers = random_layers()
    policy = OnnxPolicy(ImportedPolicy(checked(mlp_bytes(activation=activation, layers=layers))))
    obs = np.random.default_rng(2).normal(size=(64, OBS_DIM))
    expected = numpy_mean(layers, obs.astype(np.float32), activation)
    got = policy.actions(obs)
    assert got.dtype == np.float32 and got.shape == (64, ACT_DIM)
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(policy(obs[3]), got[3])  # one observation, as the judges act


def test_the_normalisation_comes_first_as_acvs_normaliser_computes_it() -> None:
    norm = normalisation()
    acv = ObsNormalizer((OBS_DIM,), clip=norm.clip)
    acv.rms.mean, acv.rms.var = norm.mean, norm.var
    obs = np.random.default_rng(3).normal(scale=4, size=(32, OBS_DIM))
    np.testing.assert_array_equal(norm(obs), acv(obs))  # bit for bit, clipping included
    layers = random_layers()
    policy = OnnxPolicy(ImportedPolicy(checked(mlp_bytes(layers=layers)), norm))
    np.testing.assert_allclose(policy.actions(obs), numpy_mean(layers, norm(obs)), atol=1e-5)


def test_the_normalisation_round_trips_through_its_npz() -> None:
    norm = normalisation()
    back = ObsNormalisation.from_npz(norm.to_npz(), obs_dim=OBS_DIM)
    assert back.content() == norm.content()


def npz(**arrays: object) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


GOOD = {"mean": np.zeros(OBS_DIM), "var": np.ones(OBS_DIM), "clip": 10.0, "epsilon": 1e-8}


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"epsilon": None}, "lacks epsilon"),
        ({"mean": np.zeros(OBS_DIM + 1)}, r"mean is float64 \(12,\)"),
        ({"var": -np.ones(OBS_DIM)}, "negative"),
        ({"var": np.full(OBS_DIM, np.nan)}, "not finite"),
        ({"clip": 0.0}, "clip must be a finite number above 0"),
        ({"mean": np.array([object()] * OBS_DIM)}, "not a readable .npz"),  # a pickle: refused
    ],
)
def test_a_bad_normalisation_file_is_refused(change: dict[str, object], match: str) -> None:
    arrays = {k: v for k, v in (GOOD | change).items() if v is not None}
    with pytest.raises(InputError, match=match):
        ObsNormalisation.from_npz(npz(**arrays), obs_dim=OBS_DIM)


def test_a_normalisation_that_is_not_a_zip_or_inflates_too_far_is_refused() -> None:
    with pytest.raises(InputError, match="not a readable .npz"):
        ObsNormalisation.from_npz(b"mean,var\n0,1\n", obs_dim=OBS_DIM)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as bomb:
        bomb.writestr("mean.npy", b"\0" * (MAX_NPZ_BYTES + 1))
    with pytest.raises(InputError, match="inflates to over"):
        ObsNormalisation.from_npz(buffer.getvalue(), obs_dim=OBS_DIM)


@pytest.mark.parametrize("how", BREAKS)
def test_a_broken_normalisation_zip_is_an_input_error(how: str) -> None:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **GOOD)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="not a readable .npz"):
        ObsNormalisation.from_npz(broken_first_member(buffer.getvalue(), how), obs_dim=OBS_DIM)


def test_the_cache_key_covers_the_normalisation() -> None:
    model = checked(mlp_bytes())
    plain, normalised = ImportedPolicy(model), ImportedPolicy(model, normalisation())
    assert plain.digest == model.digest
    assert normalised.digest not in (model.digest, ImportedPolicy(model, normalisation(2)).digest)


def test_a_normalisation_of_another_size_is_refused() -> None:
    wrong = ObsNormalisation(np.zeros(4), np.ones(4), 10.0, 1e-8)
    with pytest.raises(InputError, match="normalisation is for 4 observation entries"):
        ImportedPolicy(checked(mlp_bytes()), wrong)


def test_an_action_that_is_not_finite_is_an_input_error() -> None:
    zero = helper.make_node("Sub", ["y", "y"], ["zero"])
    divide = helper.make_node("Div", ["y", "zero"], ["z"])  # inf and nan
    policy = OnnxPolicy(ImportedPolicy(checked(linear_graph([zero, divide], "z"))))
    with pytest.raises(InputError, match="not finite"):
        policy(np.ones(OBS_DIM))


def test_layers_that_do_not_chain_are_refused_by_the_builder() -> None:
    layers = random_layers()
    layers[1] = (layers[1][0][:, :5], layers[1][1])
    with pytest.raises(InputError, match="layer 1 has weight"):
        mlp_onnx(layers, env_id=ENV)
    with pytest.raises(InputError, match="unknown activation"):
        mlp_onnx(random_layers(), env_id=ENV, activation="gelu")
