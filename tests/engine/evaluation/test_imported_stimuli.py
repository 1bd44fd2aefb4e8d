"""An imported policy's evaluation stimuli (issues 41 and 44): rolled out in the judges'
limited child process, with the checkpoints' seeds, steps and burn-in, the same states every
time and as in this process; windows cached by the policy's content, stills rendered as a
checkpoint's."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from engine.errors import InputError
from engine.evaluation import imported
from engine.evaluation.imported import (
    imported_episodes,
    imported_windows,
    pack_episodes,
    render_imported_stimuli,
    unpack_episodes,
)
from engine.evaluation.stimuli import STIMULUS_SEED0, StimulusOptions, policy_episodes
from engine.policies.normalisation import ObsNormalisation
from engine.policies.onnx_check import check_onnx
from engine.policies.onnx_policy import ImportedPolicy, OnnxPolicy
from engine.render import RenderService
from tests.support.agents import obs_norm, policy
from tests.support.onnx_models import ACT_DIM, ENV, OBS_DIM

pytestmark = pytest.mark.process  # each rollout starts a child: seconds of imports

#: As the checkpoints' stimulus tests: 2 windows of 0.4 s after a 25-step burn-in, 64 px.
OPTIONS = StimulusOptions(windows=2, clip_s=0.4, burn_in_s=0.2, size=64, clips=False)
NAME = re.compile(r"^[0-9a-f]{2}/[0-9a-f]{40}\.jpg$")


def hopper(seed: int = 0, *, normalised: bool = True) -> ImportedPolicy:
    """A tiny Hopper-v5 ONNX policy, checked as an upload is, with the tests' normalisation."""
    model = check_onnx(policy(seed), env_id=ENV, obs_dim=OBS_DIM, act_dim=ACT_DIM)
    norm = ObsNormalisation.from_npz(obs_norm(), obs_dim=OBS_DIM) if normalised else None
    return ImportedPolicy(model, norm)


@pytest.fixture(scope="module")
def service() -> Iterator[RenderService]:
    with RenderService() as svc:
        yield svc


def test_imported_rollouts_are_deterministic_and_as_in_process() -> None:
    first, second = (imported_episodes(hopper(), OPTIONS) for _ in range(2))
    here = policy_episodes(OnnxPolicy(hopper()), ENV, OPTIONS)
    assert [e.seed for e in first] == [STIMULUS_SEED0, STIMULUS_SEED0 + 1]
    for a, b, c in zip(first, second, here, strict=True):
        assert len(a.qpos) > 1 and a.burn_in == min(25, len(a.qpos)) and a.dt == c.dt
        np.testing.assert_array_equal(a.qpos, b.qpos)
        np.testing.assert_array_equal(a.qvel, b.qvel)
        np.testing.assert_array_equal(a.qpos, c.qpos)
        np.testing.assert_array_equal(a.qvel, c.qvel)
        assert (a.seed, a.burn_in, a.ended) == (c.seed, c.burn_in, c.ended)
    assert not np.array_equal(first[0].qpos[:5], first[1].qpos[:5])  # reset seeds differ


def test_windows_are_cached_by_the_policys_content(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A second call rolls nothing out; another normalisation is another policy."""
    first = imported_windows(hopper(), OPTIONS, tmp_path)

    def no_child(*_: object) -> np.ndarray:
        raise AssertionError("rolled out again")

    monkeypatch.setattr(imported, "run_in_child", no_child)
    again = imported_windows(hopper(), OPTIONS, tmp_path)
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a.qpos, b.qpos)
        assert (a.start, a.still_frame, a.frame_ms) == (b.start, b.still_frame, b.frame_ms)
    assert len(list((tmp_path / "windows").iterdir())) == 1
    with pytest.raises(AssertionError, match="rolled out again"):
        imported_windows(hopper(normalised=False), OPTIONS, tmp_path)


def test_stills_render_as_a_checkpoints(tmp_path: Path, service: RenderService) -> None:
    stimuli = render_imported_stimuli(hopper(1), ENV, OPTIONS, tmp_path, service=service)
    assert [s.window for s in stimuli] == [0, 1]
    for s in stimuli:
        assert NAME.match(s.still) and s.clip is None
        assert Image.open(tmp_path / s.still).format == "JPEG"


def test_a_policy_of_another_env_is_refused(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="for Hopper-v5, not Walker2d-v5"):
        render_imported_stimuli(hopper(), "Walker2d-v5", OPTIONS, tmp_path)


def test_a_packed_array_that_was_not_asked_for_is_refused() -> None:
    episodes = policy_episodes(OnnxPolicy(hopper()), ENV, OPTIONS)
    packed = pack_episodes(episodes)
    assert len(unpack_episodes(packed, ENV, OPTIONS)) == 2
    with pytest.raises(InputError, match="came back as"):
        unpack_episodes(packed[:, 1:], ENV, OPTIONS)
    with pytest.raises(InputError, match="not asked for"):
        unpack_episodes(pack_episodes(episodes * 2), ENV, OPTIONS)
