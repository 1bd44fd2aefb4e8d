"""Settings of the training workers, read from the environment (``ACV_`` prefix).

- ``ACV_RAY_ADDRESS``: a Ray cluster address (``host:port``); when set, each run is a Ray task
  on the cluster (the ``ray`` executor), else a process on this machine (``local``). The
  worker's machine must have joined that cluster (``ray start --address=host:port``).
- ``ACV_RUNS_DIR`` (default ``ACV_DATA_DIR/runs``): run directories (``<runs dir>/<id>``);
  with Ray it must be storage that every node and the web server can reach (NFS, ...).
- ``ACV_WORKER_SLOTS`` (default 1): runs one worker trains at the same time.
- ``ACV_BACKFILL_S`` (default 60): while idle, a worker looks this often for ended runs whose
  checkpoints have no artefact yet (the one a stop writes, failed judgings, runs older than
  artefacts) and judges them in a process of its own; 0 turns that off (``acv worker
  --backfill`` then does it on demand).
- ``ACV_SPLIT_LONE_RUN`` (default false): with one slot and at least 2 CPUs, a run that starts
  while no other run is running steps half of its envs in a helper process
  (:class:`engine.rl.split_vecenv.SplitVectorEnv`): the same numbers, faster only when the second
  core is idle (docs/scale.md, "The second core for a lone run").
- ``ACV_RUN_WORKER`` (default true): start a worker inside the web server; set it to false
  when ``acv worker`` processes run elsewhere.
"""

from __future__ import annotations

import os
from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from app.settings import Settings

#: Set by the local executor in a run process's environment: "1" when that run may split its
#: envs over two processes if it is alone (:meth:`JobSettings.splits_lone_runs`).
SPLIT_ENV = "ACV_SPLIT_THIS_RUN"


class JobSettings(BaseSettings):
    """How training runs are executed; frozen once built."""

    model_config = SettingsConfigDict(env_prefix="ACV_", extra="ignore", frozen=True)

    ray_address: str | None = None
    runs_dir: Path | None = None
    worker_slots: int = Field(default=1, ge=1, le=64)
    run_worker: bool = True
    poll_s: float = Field(default=1.0, gt=0, le=60)
    """seconds between two looks at the queue"""
    backfill_s: float = Field(default=60.0, ge=0, le=86400)
    """seconds between two looks for unjudged checkpoints of ended runs (0: never)"""
    split_lone_run: bool = False
    """a lone run (one slot, no other run running) steps half of its envs in a helper process"""

    @property
    def splits_lone_runs(self) -> bool:
        """Whether this worker's runs may take the second core: one slot, at least 2 CPUs."""
        return self.split_lone_run and self.worker_slots == 1 and (os.cpu_count() or 1) >= 2

    @property
    def executor(self) -> str:
        """``ray`` when a cluster address is set, else ``local``."""
        return "ray" if self.ray_address else "local"

    def runs_root(self, settings: Settings) -> Path:
        """Where run directories live."""
        return self.runs_dir if self.runs_dir is not None else settings.data_dir / "runs"


def run_dir(runs_dir: Path | str, run_id: int) -> Path:
    """``<runs dir>/<id>``: the run's config, metrics, checkpoints and logs."""
    return Path(runs_dir) / str(run_id)
