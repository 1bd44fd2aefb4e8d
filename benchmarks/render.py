"""Rendering throughput: the product's path against a bare ``mujoco.Renderer``, one run.

Both render the same candidate states with the same settings (view, size, no multisampling,
shadows or reflections). The product path is ``RenderService.render_many``: render thread,
encoding and a content-addressed cache write (a fresh cache directory each round, so every
frame is rendered). The bare path is ``update_scene`` + ``render`` in a loop, no encoding.
Rounds alternate the two (and which goes first) so that load from other processes hits both
alike; ``ratio`` is the median over rounds of ``bare time / product time``, robust to bursts of
load on a shared machine (``ratio_total`` uses the summed times; ``load_avg`` is reported).
Also times a study's worth of candidates from a fresh service (env, renderer and thread
creation included, backend selection reported apart).

Usage:
    python benchmarks/render.py [--candidates 64] [--size 480] [--format jpg] [--rounds 5]

The last line printed is one JSON object with ``product_fps``, ``bare_fps`` and ``ratio``.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from engine.candidates import sample_candidates
from engine.envs import make_env, restore
from engine.render import RenderCache, RenderService, RenderSpec, activate
from engine.render.renderer import configure, set_fast_flags
from engine.render.views import VIEWS

State = tuple[np.ndarray, np.ndarray]


def bare_seconds(env_id: str, states: list[State], spec: RenderSpec) -> float:
    """Seconds for a plain ``mujoco.Renderer`` to render ``states`` (renderer made outside)."""
    env = make_env(env_id)
    model, data = env.unwrapped.model, env.unwrapped.data
    configure(model, spec.size, spec.quality)
    with mujoco.Renderer(model, height=spec.size, width=spec.size) as renderer:
        set_fast_flags(renderer, spec.quality)
        camera = VIEWS[spec.view].camera()
        start = time.perf_counter()
        for qpos, qvel in states:
            restore(env, qpos, qvel)
            renderer.update_scene(data, camera)
            renderer.render()
        elapsed = time.perf_counter() - start
    env.close()
    return elapsed


def product_seconds(
    service: RenderService, env_id: str, states: list[State], spec: RenderSpec, cache_dir: Path
) -> float:
    """Seconds for the product path, cache writes into the empty ``cache_dir`` included."""
    service.cache = RenderCache(cache_dir)
    start = time.perf_counter()
    images = list(service.iter_render(env_id, states, spec))
    elapsed = time.perf_counter() - start
    assert len(images) == len(states) and all(images)
    return elapsed


def study_seconds(env_id: str, states: list[State], spec: RenderSpec, warm: bool) -> float:
    """Seconds to render a study's candidates with a new service: from its creation (cold:
    the CLI's case), or after :meth:`RenderService.warm_up` (a running web app's case)."""
    with RenderService() as service:
        if warm:
            service.warm_up(env_id, spec.view, spec.size)
        start = time.perf_counter()
        service.render_many(env_id, states, spec.view, spec.size, spec.fmt)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="Humanoid-v5")
    parser.add_argument("--candidates", type=int, default=64)
    parser.add_argument("--size", type=int, default=480)
    parser.add_argument("--format", default="jpg")
    parser.add_argument("--view", default="side")
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    spec = RenderSpec(view=args.view, size=args.size, fmt=args.format)
    start = time.perf_counter()
    backend = activate()
    backend_s = time.perf_counter() - start
    candidates = sample_candidates(args.env, args.candidates, rng=np.random.default_rng(args.seed))
    states = [(c.qpos, c.qvel) for c in candidates]
    study_cold_s = study_seconds(args.env, states, spec, warm=False)
    study_warm_s = study_seconds(args.env, states, spec, warm=True)

    product, bare = [], []
    with RenderService() as service, tempfile.TemporaryDirectory() as tmp:
        service.render_many(args.env, states[:1], spec.view, spec.size, spec.fmt)  # warm up
        for r in range(args.rounds):
            cache_dir = Path(tmp) / str(r)
            if r % 2:  # alternate which path goes first
                bare.append(bare_seconds(args.env, states, spec))
                product.append(product_seconds(service, args.env, states, spec, cache_dir))
            else:
                product.append(product_seconds(service, args.env, states, spec, cache_dir))
                bare.append(bare_seconds(args.env, states, spec))
            print(
                f"round {r}: product {len(states) / product[-1]:.1f} fps, "
                f"bare {len(states) / bare[-1]:.1f} fps"
            )

    frames = args.rounds * len(states)
    result = {
        "env": args.env,
        "view": spec.view,
        "size": spec.size,
        "format": spec.fmt,
        "backend": backend,
        "frames": frames,
        "product_fps": round(frames / sum(product), 1),
        "bare_fps": round(frames / sum(bare), 1),
        "ratio": round(float(np.median(np.array(bare) / np.array(product))), 3),
        "ratio_total": round(sum(bare) / sum(product), 3),
        "study_candidates": len(states),
        "study_s": round(study_cold_s, 3),
        "study_warm_s": round(study_warm_s, 3),
        "backend_select_s": round(backend_s, 3),
        "load_avg": [round(x, 2) for x in os.getloadavg()],
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
