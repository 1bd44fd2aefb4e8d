"""Connecting to a Ray cluster, as every part of ACV that runs work there does (the ``ray``
run executor, ``acv validate``): this process becomes a driver of the cluster at ``address``
(``host:port``), of which this machine must be a node (Ray Client is not used: it ends the
tasks of a driver whose connection drops for 30 s, while runs last hours)."""

from __future__ import annotations

import logging
from types import ModuleType


def connect(address: str) -> ModuleType:
    """The ``ray`` module, connected to the cluster at ``address`` (once per process)."""
    import ray  # optional dependency (the ``ray`` extra): only work on a cluster needs it

    if not ray.is_initialized():
        ray.init(
            address=address,
            namespace="acv",
            logging_level=logging.WARNING,
            log_to_driver=False,
            configure_logging=False,
        )
    return ray
