"""Background training runs: a job queue on the database, executors, and the worker loop.

- :mod:`app.jobs.queue`: the ``runs`` table as a queue: atomic claims (two workers never take
  the same run), heartbeats, final states, and recovery of runs whose worker is gone.
- :mod:`app.jobs.execute`: one run from start to end (the same code in a local process and in
  a Ray task): progress rows to the database, cancellation, the final state.
- :mod:`app.jobs.run_process`: a run in its own process (the ``local`` executor forks it
  from a fork server that has imported torch once).
- :mod:`app.jobs.local` and :mod:`app.jobs.ray_executor`: the ``local`` and ``ray`` executors.
- :mod:`app.jobs.worker`: claims queued runs and hands them to an executor; started with the
  server (:func:`app.jobs.worker.start_app_worker`) or standalone by ``acv worker``.
"""
