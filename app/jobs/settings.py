"""Settings of the training workers, read from the environment (``ACV_`` prefix).

- ``ACV_RAY_ADDRESS``: a Ray cluster address (``host:port``); when set, each run is a Ray task
  on the cluster (the ``ray`` executor), else a process on this machine (``local``). The
  worker's machine must have joined that cluster (``ray start --address=host:port``).
- ``ACV_RUNS_DIR`` (default ``ACV_DATA_DIR/runs``): run directories (``<runs dir>/<id>``);
  with Ray it must be storage that every node and the web server can reach (NFS, ...).
- ``ACV_WORKER_SLOTS`` (default 1): runs one worker trains at the same time.
- ``ACV_RUN_WORKER`` (default true): start a worker inside the web server; set it to false
  when ``acv worker`` processes run elsewhere.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from app.settings import Settings


class JobSettings(BaseSettings):
    """How training runs are executed; frozen once built."""

    model_config = SettingsConfigDict(env_prefix="ACV_", extra="ignore", frozen=True)

    ray_address: str | None = None
    runs_dir: Path | None = None
    worker_slots: int = Field(default=1, ge=1, le=64)
    run_worker: bool = True
    poll_s: float = Field(default=1.0, gt=0, le=60)
    """seconds between two looks at the queue"""

    @property
    def executor(self) -> str:
        """``ray`` when a cluster address is set, else ``local``."""
        return "ray" if self.ray_address else "local"

    def runs_root(self, settings: Settings) -> Path:
        """Where run directories live."""
        return self.runs_dir if self.runs_dir is not None else settings.data_dir / "runs"
