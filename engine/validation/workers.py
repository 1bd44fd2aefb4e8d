"""Where a validation's runs train and are measured: processes on this machine, or tasks on a
Ray cluster. Free of torch and MuJoCo, so that the CLI can name it without importing them."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from typing import Any, TypeVar

from engine.ray_cluster import connect

Task = tuple[str, int]  # (arm name, seed)


T = TypeVar("T")


@dataclass(frozen=True)
class Workers:
    """Where runs train and are measured: ``jobs`` processes on this machine (this one
    process when ``jobs`` is 1), or one Ray task of one CPU per run on the cluster at
    ``ray_address`` (``host:port``), as many at once as it has CPUs. With Ray, this machine
    must be a node of the cluster (as for the ``ray`` run executor) and the validation folder
    on storage that every node reaches."""

    jobs: int = 1
    ray_address: str | None = None

    def map(self, work: Callable[[Task], T], tasks: list[Task]) -> list[T]:
        """``work`` of every task, in the order of ``tasks``; the first failure stops the
        rest. ``work`` must be picklable unless it runs here: a module-level function or a
        ``partial`` of one."""
        if self.ray_address is not None:
            return _on_ray(work, tasks, self.ray_address)
        if self.jobs <= 1:
            return [work(task) for task in tasks]
        # Runs are independent and single-threaded: processes give a near-linear speed-up;
        # spawn, because torch and MuJoCo are not fork-safe.
        with ProcessPoolExecutor(max_workers=self.jobs, mp_context=get_context("spawn")) as pool:
            futures = [pool.submit(work, task) for task in tasks]
            try:
                return [future.result() for future in futures]
            except BaseException:  # report a failed run now, not after every queued run
                pool.shutdown(cancel_futures=True)
                raise


def _on_ray(work: Callable[[Task], T], tasks: list[Task], address: str) -> list[T]:
    ray = connect(address)
    remote: Any = ray.remote(num_cpus=1, max_retries=0)(_call)
    refs = [remote.remote(work, task) for task in tasks]
    try:
        return list(ray.get(refs))
    except BaseException:  # a failed run stops the rest, as on this machine
        for ref in refs:
            ray.cancel(ref)
        raise


def _call(work: Callable[[Task], T], task: Task) -> T:
    return work(task)
