"""A Stable-Baselines3 ``.zip`` converted to ONNX without unpickling anything.

``model.save`` writes a zip whose ``data`` member is JSON in which every non-JSON value (the
policy class, the spaces, schedules) is a cloudpickle in base64 under ``":serialized:"``, and
whose ``policy.pth`` is the policy's ``state_dict``. SB3's own ``load`` unpickles both, which
runs whatever code the file's author put there. Here:

- ``policy.pth`` is read with ``torch.load(weights_only=True)``: tensors only;
- of ``data``, only the top-level plain JSON values are kept (numbers, strings, booleans,
  null): the declared training settings; every dict is left unread, the pickled ones included;
- only an on-policy ``MlpPolicy`` (PPO, A2C) is accepted: ``mlp_extractor.policy_net.*`` and
  ``action_net.*`` (the mean), ``mlp_extractor.value_net.*``, ``value_net.*`` and ``log_std``
  (read by nothing here); any other parameter (a CNN, SAC's ``actor.*``) is refused;
- the activation cannot be read without unpickling ``policy_kwargs``, so the caller names it
  (SB3's default, ``tanh``, or ``relu``);
- every member is checked against a size cap (``ZipInfo.file_size``) before it is read, so a
  zip bomb inflates nothing.

The result is checked by :func:`engine.policies.onnx_check.check_onnx`, the gate every stored
policy passes. SB3's deterministic ``predict`` is the mean, clipped to the action space: the
judges clip it the same way.
"""

from __future__ import annotations

import io
import json
import pickle
import re
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import torch

from engine.envs import env_dims
from engine.errors import InputError
from engine.policies.onnx_build import ACTIVATIONS, Layer, mlp_onnx
from engine.policies.onnx_check import CheckedOnnx, OnnxLimits, check_onnx

MiB = 1024 * 1024
_POLICY_NET = re.compile(r"^mlp_extractor\.policy_net\.(\d+)\.(weight|bias)$")
#: The parameters an MlpPolicy has besides the mean's, which the mean does not read.
_UNUSED = re.compile(
    r"^(log_std|mlp_extractor\.value_net\.\d+\.(weight|bias)|value_net\.(weight|bias))$"
)
_ACTION_NET = ("action_net.weight", "action_net.bias")
#: Declared settings are plain JSON scalars.
Declared = dict[str, int | float | str | bool | None]


@dataclass(frozen=True)
class Sb3Limits:
    """Caps on an SB3 save.

    Attributes:
        max_zip_bytes: the zip file.
        max_policy_bytes: ``policy.pth`` uncompressed.
        max_data_bytes: ``data`` uncompressed.
    """

    max_zip_bytes: int = 256 * MiB
    max_policy_bytes: int = 64 * MiB
    max_data_bytes: int = 4 * MiB


@dataclass(frozen=True)
class Sb3Policy:
    """An SB3 policy converted and checked.

    Attributes:
        model: the ONNX model, checked.
        declared: the plain JSON values of the save's ``data`` (``num_timesteps``, ``seed``,
            ``n_envs``, ``gamma``, ...): what the trainer says, which ACV did not see happen.
    """

    model: CheckedOnnx
    declared: Declared = field(default_factory=dict, hash=False)


def sb3_to_onnx(
    data: bytes,
    *,
    env_id: str,
    activation: str = "tanh",
    limits: Sb3Limits = Sb3Limits(),
    onnx_limits: OnnxLimits = OnnxLimits(),
) -> Sb3Policy:
    """Convert an SB3 ``MlpPolicy`` save's mean action to a checked ONNX model.

    Args:
        data: the ``.zip`` file's bytes.
        env_id: the env it was trained on (written into the model's metadata).
        activation: ``tanh`` (SB3's default) or ``relu``, as in the policy's ``activation_fn``.
        limits: the zip's caps.
        onnx_limits: the converted model's (:func:`check_onnx`).

    Raises:
        InputError: over a cap, not an SB3 save, not an MlpPolicy, or sizes that do not fit
            the env.
    """
    if activation not in ACTIVATIONS:
        raise InputError(f"unknown activation {activation!r}: expected {', '.join(ACTIVATIONS)}")
    if len(data) > limits.max_zip_bytes:
        raise InputError(f"the SB3 file is over the limit of {limits.max_zip_bytes} bytes")
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            settings = _member(archive, "data", limits.max_data_bytes)
            weights = _member(archive, "policy.pth", limits.max_policy_bytes)
    except (zipfile.BadZipFile, zipfile.LargeZipFile) as exc:
        raise InputError(f"not an SB3 save: the file is not a readable zip ({exc})") from exc
    declared = plain_fields(settings)
    layers = mlp_layers(_state_dict(weights))
    metadata = {"producer": "stable-baselines3 (converted by acv)", "activation": activation}
    onnx_bytes = mlp_onnx(layers, env_id=env_id, activation=activation, metadata=metadata)
    obs_dim, act_dim = env_dims(env_id)
    checked = check_onnx(
        onnx_bytes, env_id=env_id, obs_dim=obs_dim, act_dim=act_dim, limits=onnx_limits
    )
    return Sb3Policy(checked, declared)


def _member(archive: zipfile.ZipFile, name: str, cap: int) -> bytes:
    """A member's bytes, refused before reading when its declared size is over ``cap``
    (zipfile stops reading at the declared size, so a lying header inflates no further)."""
    try:
        info = archive.getinfo(name)
    except KeyError:
        raise InputError(f"not an SB3 save: the zip has no {name!r}") from None
    if info.file_size > cap:
        raise InputError(f"the SB3 file's {name!r} inflates to {info.file_size} bytes, over {cap}")
    try:
        return archive.read(info)
    except (RuntimeError, ValueError, OSError, EOFError, zlib.error) as exc:  # encrypted, corrupt
        raise InputError(f"the SB3 file's {name!r} cannot be read ({exc})") from exc


def plain_fields(settings: bytes) -> Declared:
    """The top-level plain JSON values of an SB3 ``data`` member; dicts and lists, among them
    the pickled values, are left unread.

    Raises:
        InputError: not a JSON object.
    """
    try:
        parsed = json.loads(settings)
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise InputError(f"not an SB3 save: its 'data' is not JSON ({exc})") from exc
    if not isinstance(parsed, dict):
        raise InputError("not an SB3 save: its 'data' is not a JSON object")
    plain = (int, float, str, bool, type(None))
    return {k: v for k, v in parsed.items() if isinstance(v, plain)}


def _state_dict(weights: bytes) -> Mapping[str, torch.Tensor]:
    try:
        state = torch.load(io.BytesIO(weights), map_location="cpu", weights_only=True)
    except (RuntimeError, pickle.UnpicklingError, ValueError, EOFError, OSError) as exc:
        raise InputError(
            f"the SB3 file's 'policy.pth' is not a plain state dict of tensors ({exc})"
        ) from exc
    if not isinstance(state, Mapping) or not all(
        isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in state.items()
    ):
        raise InputError("the SB3 file's 'policy.pth' is not a state dict of tensors")
    for key, value in state.items():  # sparse or complex ones would not convert, or lose parts
        if value.layout != torch.strided or not value.dtype.is_floating_point:
            raise InputError(
                f"the SB3 file's {key!r} is {value.layout} {value.dtype}: not a dense tensor "
                "of floats"
            )
    return state


def mlp_layers(state: Mapping[str, torch.Tensor]) -> list[Layer]:
    """The mean's layers of an SB3 ``MlpPolicy`` state dict: ``policy_net`` then ``action_net``.

    Raises:
        InputError: a parameter no MlpPolicy has, or the layers are not Linear, act, Linear...
    """
    hidden: dict[int, dict[str, Any]] = {}
    for key in state:
        if match := _POLICY_NET.match(key):
            hidden.setdefault(int(match.group(1)), {})[match.group(2)] = state[key]
        elif key not in _ACTION_NET and not _UNUSED.match(key):
            raise InputError(
                f"not an SB3 MlpPolicy: it has the parameter {key!r} (accepted: PPO and A2C "
                "MlpPolicy, whose mean is mlp_extractor.policy_net and action_net)"
            )
    if any(name not in state for name in _ACTION_NET):
        raise InputError("not an SB3 MlpPolicy: it has no action_net")
    indices = sorted(hidden)
    if indices != list(range(0, 2 * len(indices), 2)) or any(
        set(p) != {"weight", "bias"} for p in hidden.values()
    ):
        raise InputError(
            f"not an SB3 MlpPolicy: policy_net's layers are {indices}, not Linear layers at "
            "0, 2, 4, ... with an activation between them"
        )
    layers = [(hidden[i]["weight"], hidden[i]["bias"]) for i in indices]
    layers.append((state["action_net.weight"], state["action_net.bias"]))
    return [
        (w.detach().float().numpy().copy(), b.detach().float().numpy().copy()) for w, b in layers
    ]
