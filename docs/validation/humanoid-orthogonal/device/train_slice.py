"""Advance validation runs on the device machine's 16 cores until a deadline, then pack them.

Usage: python train_slice.py STATE_DIR DEADLINE_S OUT_DIR TASK... (TASK: arm-seed, e.g. p1-10-3)
Each run stops cleanly at the deadline (train() writes a checkpoint on stop) and its folder is
packed with only its latest checkpoint, to resume exactly where it stopped on another machine.
Also: resume n1-0 from its 100,352-step checkpoint to 200,704 and compare every metrics row with
the same rows trained on the 2-core machine (cross-machine exactness).
"""
import json, os, sys, tarfile, time, multiprocessing as mp

PARITY_TO = int(os.environ.get("PARITY_TO", "200704"))
from pathlib import Path


def split(task):
    arm, seed = task.rsplit("-", 1)
    return arm, int(seed)


def advance(state_dir, deadline, task):
    try:
        return _advance(state_dir, deadline, task)
    except Exception as exc:
        return task, repr(exc)


def _advance(state_dir, deadline, task):
    from engine.rl.runner import train
    from engine.treefile import load_tree
    from engine.validation import runs
    from engine.validation.design import ARM_BY_NAME, AdviceKind, Plan
    out = Path(state_dir)
    plan = Plan.from_json(runs.read_json(out / runs.PLAN_FILE))
    arm_name, seed = split(task)
    arm = ARM_BY_NAME[arm_name]
    advice = None if arm.advice is AdviceKind.NONE else load_tree(runs.advice_path(out, arm))
    folder = runs.run_dir(out, arm_name, seed)
    t0 = time.time()
    train(runs.train_config(plan, arm, seed), advice, folder, should_stop=lambda: time.time() > deadline, resume=True)
    return task, time.time() - t0


def parity(state_dir):
    try:
        return _parity(state_dir)
    except Exception as exc:  # the training must still come back
        return {"error": repr(exc)}


def _parity(state_dir):
    from engine.rl.runner import train, load_run_config
    folder = Path(state_dir) / "parity" / "n1-0"
    reference = [json.loads(l) for l in (folder / "reference.jsonl").read_text().splitlines()]
    last = {"t": 0}
    def progress(row):
        last["t"] = row["timesteps"]
    train(load_run_config(folder), None, folder, progress=progress, resume=True,
          should_stop=lambda: last["t"] >= PARITY_TO)
    mine = [json.loads(l) for l in (folder / "metrics.jsonl").read_text().splitlines()]
    mine = {r["timesteps"]: r for r in mine if 100352 < r["timesteps"] <= PARITY_TO}
    ref = {r["timesteps"]: r for r in reference if 100352 < r["timesteps"] <= PARITY_TO}
    diffs = [(t, k, ref[t][k], mine[t].get(k)) for t in ref for k in ref[t]
             if k not in ("sps", "time") and (t not in mine or mine[t].get(k) != ref[t][k])]
    return {"rows_compared": len(ref), "rows_here": len(mine), "differences": diffs[:20],
            "n_differences": len(diffs)}


def pack(state_dir, tasks, out_dir):
    groups = [tasks[i::4] for i in range(4)]
    for g, group in enumerate(groups):
        with tarfile.open(Path(out_dir) / f"runs_{g}.tar", "w") as tar:
            for task in group:
                folder = Path(state_dir) / "runs" / task
                ckpts = sorted(folder.glob("checkpoints/step_*.pt"), key=lambda p: int(p.stem[5:]))
                for p in folder.iterdir():
                    if p.is_file():
                        tar.add(p, arcname=f"{task}/{p.name}")
                if ckpts:
                    tar.add(ckpts[-1], arcname=f"{task}/checkpoints/{ckpts[-1].name}")


if __name__ == "__main__":
    state_dir, budget, out_dir, *tasks = sys.argv[1:]
    deadline = time.time() + float(budget)
    ctx = mp.get_context("spawn")
    with ctx.Pool(len(tasks) + 1) as pool:
        check = pool.apply_async(parity, (state_dir,))
        done = pool.starmap_async(advance, [(state_dir, deadline, t) for t in tasks])
        result = {"parity": check.get(), "trained": done.get()}
    pack(state_dir, tasks, out_dir)
    for task in tasks:
        metrics = Path(state_dir) / "runs" / task / "metrics.jsonl"
        rows = metrics.read_text().splitlines() if metrics.is_file() else []
        result.setdefault("steps", {})[task] = json.loads(rows[-1])["timesteps"] if rows else 0
        result.setdefault("return_100", {})[task] = json.loads(rows[-1])["return_100"] if rows else None
    (Path(out_dir) / "result.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))
