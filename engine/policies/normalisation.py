"""An imported policy's observation normalisation: plain arrays in an ``.npz``, no pickle.

A policy trained under Stable-Baselines3's ``VecNormalize`` (or ACV's own
:class:`~engine.rl.normalize.ObsNormalizer`) sees ``clip((obs - mean) / sqrt(var + epsilon),
-clip, clip)``, computed in float64 and then cast to float32, before its network. That step
stays outside the ONNX graph, as it does in SB3: the graph's input is float32, so folding it in
would normalise an observation already rounded to float32, and the actions would differ from
the training path's in the last bits (which MuJoCo rollouts then amplify).

SB3 saves ``VecNormalize`` with pickle, which ACV never loads; the three lines that write the
``.npz`` on the trainer's own machine::

    vec_normalize = VecNormalize.load("vec_normalize.pkl", venv)
    rms = vec_normalize.obs_rms
    np.savez("obs_norm.npz", mean=rms.mean, var=rms.var, clip=vec_normalize.clip_obs,
             epsilon=vec_normalize.epsilon)
"""

from __future__ import annotations

import io
import zipfile
import zlib
from dataclasses import dataclass

import numpy as np

from engine.errors import InputError

#: The arrays of the file, each ``<name>.npy`` in the zip that ``np.savez`` writes.
FIELDS = ("mean", "var", "clip", "epsilon")
#: The file's size, and its members' uncompressed size together (an ``.npz`` is a zip: a small
#: file could inflate to gigabytes). 16 MiB holds mean and var of a million float64 values.
MAX_NPZ_BYTES = 16 * 1024 * 1024


@dataclass(frozen=True, eq=False)
class ObsNormalisation:
    """``clip((obs - mean) / sqrt(var + epsilon), -clip, clip)`` as float32, as SB3's
    ``VecNormalize.normalize_obs`` and ACV's ``ObsNormalizer`` compute it.

    Attributes:
        mean: float64, shape ``(obs_dim,)``.
        var: float64, shape ``(obs_dim,)``, non-negative.
        clip: the bound of a normalised value, > 0.
        epsilon: added to ``var``, > 0.
    """

    mean: np.ndarray
    var: np.ndarray
    clip: float
    epsilon: float

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Normalised float32 observations, same shape as ``obs`` (float64, ``(B, obs_dim)``)."""
        out = (obs - self.mean) / np.sqrt(self.var + self.epsilon)
        normalised: np.ndarray = np.clip(out, -self.clip, self.clip).astype(np.float32)
        return normalised

    def to_npz(self) -> bytes:
        """The ``.npz`` file's bytes (what :meth:`from_npz` reads back)."""
        buffer = io.BytesIO()
        np.savez(
            buffer,
            mean=self.mean,
            var=self.var,
            clip=np.float64(self.clip),
            epsilon=np.float64(self.epsilon),
        )
        return buffer.getvalue()

    def content(self) -> bytes:
        """The four values as bytes, for a content hash (the ``.npz`` itself carries zip
        timestamps)."""
        scalars = np.array([self.clip, self.epsilon], dtype=np.float64)
        return b"".join(np.ascontiguousarray(a).tobytes() for a in (self.mean, self.var, scalars))

    @classmethod
    def from_npz(cls, data: bytes, *, obs_dim: int) -> ObsNormalisation:
        """Read and check an ``.npz`` of :data:`FIELDS`, never unpickling.

        Raises:
            InputError: too big, not an ``.npz``, a field missing or of the wrong shape, not
                finite, a negative variance, a clip or epsilon not above 0.
        """
        arrays = _read_npz(data)
        mean, var = (_vector(arrays, name, obs_dim) for name in ("mean", "var"))
        if (var < 0).any():
            raise InputError("the normalisation's var has negative entries")
        clip, epsilon = (_positive(arrays, name) for name in ("clip", "epsilon"))
        return cls(mean, var, clip, epsilon)


def _read_npz(data: bytes) -> dict[str, np.ndarray]:
    if len(data) > MAX_NPZ_BYTES:
        raise InputError(f"the normalisation file is over {MAX_NPZ_BYTES} bytes")
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            inflated = sum(info.file_size for info in archive.infolist())
        if inflated > MAX_NPZ_BYTES:
            raise InputError(f"the normalisation file inflates to over {MAX_NPZ_BYTES} bytes")
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            missing = [name for name in FIELDS if name not in npz.files]
            if missing:
                raise InputError(
                    f"the normalisation file lacks {', '.join(missing)}: it needs "
                    f"{', '.join(FIELDS)} (see engine/policies/normalisation.py)"
                )
            return {name: npz[name] for name in FIELDS}
    # RuntimeError: an encrypted member, or (NotImplementedError) an unknown compression;
    # zlib.error: a corrupt deflate stream (np.load inflates a member only when it is read).
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, RuntimeError, zlib.error) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"the normalisation file is not a readable .npz ({exc})") from exc


def _vector(arrays: dict[str, np.ndarray], name: str, size: int) -> np.ndarray:
    value = arrays[name]
    if value.dtype.kind not in "fiu" or value.shape != (size,):
        raise InputError(
            f"the normalisation's {name} is {value.dtype} {value.shape}, not a number per "
            f"observation entry ({size},)"
        )
    vector = value.astype(np.float64)
    if not np.isfinite(vector).all():
        raise InputError(f"the normalisation's {name} has entries that are not finite")
    return vector


def _positive(arrays: dict[str, np.ndarray], name: str) -> float:
    value = arrays[name]
    if value.dtype.kind not in "fiu" or value.size != 1:
        raise InputError(f"the normalisation's {name} is {value.dtype} {value.shape}, not a number")
    number = float(value.reshape(()))
    if not np.isfinite(number) or number <= 0:
        raise InputError(f"the normalisation's {name} must be a finite number above 0, is {number}")
    return number
