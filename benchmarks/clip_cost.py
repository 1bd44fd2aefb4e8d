"""What motion clips cost against stills (issue 41 §3), measured in one run.

Rolls out one checkpoint with the default :class:`~engine.evaluation.stimuli.StimulusOptions`
(4 windows of 2 s, 15 fps, 480 px, on Humanoid-v5 by default), then renders the windows'
stills the product's way (a warm :class:`~engine.render.RenderService`, the web app's case)
and then their clips into the same folder (animated WebP, a renderer made per call, as the
background job does after the stills). Reports CPU seconds (``time.process_time``: every
thread of this process, the render thread included, plus any child process) and bytes per
clip against a still, and one participant's download for ``--pairs`` pairs: two clips a
pair, or two stills a pair.

Without ``--checkpoint`` an untrained agent is made on the spot: it falls within the burn-in,
so its clips are its last, shorter seconds; pass a trained run's checkpoint for real clips.

Usage:
    python benchmarks/clip_cost.py [--checkpoint PATH] [--env Humanoid-v5] [--pairs 20]

The last line printed is one JSON object. Tests never assert timings.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from engine.evaluation.clips import render_windows
from engine.evaluation.stimuli import StimulusOptions, run_windows
from engine.render import RenderService, activate
from engine.rl.checkpoint import save_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.trainer import Trainer

T = TypeVar("T")


def cpu_seconds() -> float:
    """CPU seconds of this process (all threads) and of its waited-for children."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def measured(work: Callable[[], T]) -> tuple[T, float, float]:
    """``work()``, its CPU seconds and its wall seconds."""
    cpu, wall = cpu_seconds(), time.perf_counter()
    found = work()
    return found, cpu_seconds() - cpu, time.perf_counter() - wall


def untrained_checkpoint(env_id: str, folder: Path) -> Path:
    """A checkpoint of a freshly initialised ``ppo`` agent, saved as training does."""
    cfg = TrainConfig(algo="ppo", env_id=env_id, n_envs=1, num_steps=64, num_minibatches=1)
    trainer = Trainer(cfg, None)
    try:
        return save_checkpoint(trainer.state_dict(), folder, 0)
    finally:
        trainer.envs.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", type=Path, default=None)
    parser.add_argument("--env", default="Humanoid-v5")
    parser.add_argument("--pairs", type=int, default=20)
    args = parser.parse_args()
    options = StimulusOptions()
    backend = activate()  # the backend probe's subprocesses are not part of either cost
    with tempfile.TemporaryDirectory() as tmp, RenderService() as service:
        out = Path(tmp)
        checkpoint = args.checkpoint or untrained_checkpoint(args.env, out / "run")
        windows, roll_cpu, roll_wall = measured(
            lambda: run_windows(checkpoint, args.env, options, out / "windows")
        )
        service.warm_up(args.env, options.view, options.size)
        stills, still_cpu, still_wall = measured(
            lambda: render_windows(
                args.env, windows, options.spec, out / "s", clips=False, service=service
            )
        )
        clips, clip_cpu, clip_wall = measured(
            lambda: render_windows(
                args.env, windows, options.spec, out / "s", clips=True, service=service
            )
        )
    n = len(windows)
    still_bytes = sum(s.still_bytes for s in stills) / n
    clip_bytes = sum(s.clip_bytes or 0 for s in clips) / n
    shown = 2 * args.pairs
    result = {
        "env": args.env,
        "backend": backend,
        "checkpoint": "given" if args.checkpoint else "untrained",
        "windows": n,
        "frames_per_clip": [s.n_frames for s in clips],
        "frame_ms": clips[0].frame_duration_ms,
        "rollout_cpu_s": round(roll_cpu, 3),
        "rollout_wall_s": round(roll_wall, 3),
        "still_cpu_s": round(still_cpu / n, 4),
        "clip_cpu_s": round(clip_cpu / n, 4),
        "cpu_ratio": round(clip_cpu / still_cpu, 1),
        "stills_wall_s": round(still_wall, 3),
        "clips_wall_s": round(clip_wall, 3),
        "still_bytes": round(still_bytes),
        "clip_bytes": round(clip_bytes),
        "bytes_ratio": round(clip_bytes / still_bytes, 1),
        "pairs": args.pairs,
        "download_stills_mb": round(shown * still_bytes / 1e6, 2),
        "download_clips_mb": round(shown * clip_bytes / 1e6, 2),
        "download_clips_and_posters_mb": round(shown * (clip_bytes + still_bytes) / 1e6, 2),
        "load_avg": [round(x, 2) for x in os.getloadavg()],
    }
    print(
        f"{args.env} ({result['checkpoint']} checkpoint, {backend}): {n} windows, "
        f"{result['frames_per_clip']} frames of {result['frame_ms']} ms"
    )
    print(f"rollouts: {roll_cpu:.2f} CPU s for the run ({roll_wall:.2f} s wall)")
    print(
        f"per still: {result['still_cpu_s']:.3f} CPU s, {result['still_bytes']} bytes; "
        f"per clip: {result['clip_cpu_s']:.3f} CPU s, {result['clip_bytes']} bytes; "
        f"clip/still: CPU x{result['cpu_ratio']}, bytes x{result['bytes_ratio']}"
    )
    print(
        f"one participant, {args.pairs} pairs: stills {result['download_stills_mb']} MB, "
        f"clips {result['download_clips_mb']} MB "
        f"(with their stills as posters {result['download_clips_and_posters_mb']} MB)"
    )
    print(json.dumps(result))


if __name__ == "__main__":
    main()
