"""The ``ray`` executor: each run is a Ray task on the cluster at ``ACV_RAY_ADDRESS``.

The task runs :func:`app.jobs.execute.execute_run`, exactly what a local run process runs:
it reports to the database (which every node must reach: PostgreSQL at scale) and writes its
run directory under ``ACV_RUNS_DIR``, which must be storage every node and the web server
can reach. Tasks are never retried by Ray: a run whose task dies is ``failed`` with Ray's
error, and can be resumed from its last checkpoint.

The worker connects as a driver on a node of the cluster (:func:`engine.ray_cluster.connect`,
not Ray Client): the machine of ``acv worker`` must have joined it first (``ray start
--address=host:6379``, as the compose ``worker`` service does).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

from app.jobs.execute import execute_run
from app.jobs.local import TAIL_CHARS, Finished
from engine.ray_cluster import connect

#: CPUs a run's task asks the cluster for.
TASK_CPUS = 1


class RayExecutor:
    """Submits claimed runs as Ray tasks.

    Args:
        address: the cluster's GCS address (``host:port``), as for ``ray.init``; this
            machine must be a node of that cluster.
        database_url: the database the tasks report to.
        runs_dir: the shared folder of run directories.
    """

    name = "ray"
    signals_runs = False  # tasks learn that they must stop from the database

    def __init__(self, *, address: str, database_url: str, runs_dir: Path) -> None:
        self._ray = ray = connect(address)
        # ray's stubs type a decorated function as taking no arguments; ours takes the run's
        self._task: Any = ray.remote(num_cpus=TASK_CPUS, max_retries=0)(cast(Any, execute_run))
        self.database_url = database_url
        self.runs_dir = str(Path(runs_dir).resolve())
        self.refs: dict[Any, int] = {}
        self._ended: list[Finished] = []

    def start(self, run_id: int, worker: str) -> None:
        """Submit a run ``worker`` has claimed."""
        ref = self._task.options(name=f"acv-run-{run_id}").remote(
            run_id, database_url=self.database_url, runs_dir=self.runs_dir, worker=worker
        )
        self.refs[ref] = run_id

    @property
    def active(self) -> int:
        return len(self.refs)

    def poll(self) -> list[Finished]:
        """Runs whose task has ended since the last call."""
        done, self._ended = self._ended, []
        if self.refs:
            ready, _ = self._ray.wait(list(self.refs), num_returns=len(self.refs), timeout=0)
            done += [self._result(ref) for ref in ready]
        return done

    def _result(self, ref: Any) -> Finished:
        run_id = self.refs.pop(ref)
        try:
            self._ray.get(ref)
        except self._ray.exceptions.RayError as exc:
            text = str(exc).strip()[-TAIL_CHARS:]
            return Finished(run_id, f"the Ray task failed: {type(exc).__name__}: {text}")
        return Finished(run_id, None)

    def request_stop(self) -> None:
        """Nothing to send: the worker marks the runs ``interrupted`` in the database."""

    def wait(self, timeout_s: float) -> None:
        """Wait for the tasks to end (cancel those still running after ``timeout_s``), then
        disconnect from the cluster; :meth:`poll` still reports the ended tasks."""
        if self.refs:
            ready, left = self._ray.wait(
                list(self.refs), num_returns=len(self.refs), timeout=timeout_s
            )
            self._ended += [self._result(ref) for ref in ready]
            for ref in left:
                self._ray.cancel(ref, force=True)
                self._ended.append(Finished(self.refs.pop(ref), "the Ray task was cancelled"))
        self._ray.shutdown()  # no Ray call after this: one would start a local cluster
