"""ACV engine: the paper's method as a pure library (numpy, torch, mujoco, gymnasium).

The engine never imports :mod:`app`. Algorithms that draw random numbers take an explicit
``rng: np.random.Generator``.
"""

#: ACV's version: the one source (``pyproject.toml`` reads it; ``acv --version``, the web
#: app, every run's ``provenance.json`` and the shared dataset's card show it).
__version__ = "0.2.0"
