"""ACV engine: the paper's method as a pure library (numpy, torch, mujoco, gymnasium).

The engine never imports :mod:`app`. Algorithms that draw random numbers take an explicit
``rng: np.random.Generator``.
"""
