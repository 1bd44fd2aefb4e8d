"""The agent evaluation (issue 41): a person is shown pairs of trained agents (runs) and
says which one does what they asked.

- :mod:`engine.evaluation.design`: which pairs of runs each evaluator is shown, and on which
  side.
- :mod:`engine.evaluation.stats`: the declared statistic, its exact permutation p, its
  bootstrap interval, the side-bias and between-arm rates.
- :mod:`engine.evaluation.outcome`: the declared outcome rule, its sentence by evaluator
  kind, and :func:`~engine.evaluation.outcome.evaluate`.
- :mod:`engine.evaluation.simulate`: simulated evaluators and the synthetic null with run
  effects.
- :mod:`engine.evaluation.power`: the evaluators and answers a design needs.
- :mod:`engine.evaluation.stimuli` and :mod:`engine.evaluation.clips`: what is shown of a
  run: deterministic rollouts of its checkpoint, windows of them, rendered as stills and
  animated WebP clips.

Nothing here knows the web application or the database. The statistics know no
environment either: runs are indices ``0 .. n_runs-1`` and the arms a boolean array over them.
"""
