"""Helpers shared by the tests (and by ``benchmarks/fault_load.py``): free ports, waiting for
a state, ``acv serve`` in a subprocess, the ``acv`` CLI, cookie-jar browsing with CSRF, and a
throwaway PostgreSQL cluster.

Tests import them as ``from tests.support.wait import wait_for``: pytest runs with
``--import-mode=importlib`` from the repository root, where ``tests`` is a namespace package.
"""
