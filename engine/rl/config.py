"""Training configuration: one frozen dataclass, CleanRL style (one docstring per field)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from engine.errors import InputError, seed_error


class Algo(StrEnum):
    """``ppo``: env reward only; ``ppo-shaped``: R + F (z = 1); ``bipars-*``: R + z_phi(s) F(s)."""

    PPO = "ppo"
    PPO_SHAPED = "ppo-shaped"
    BIPARS_EM = "bipars-em"
    BIPARS_MGL = "bipars-mgl"


ALGOS: tuple[str, ...] = tuple(a.value for a in Algo)

ADVISED_ALGOS: frozenset[str] = frozenset(ALGOS[1:])
"""Algorithms that need an advice reward F."""

BIPARS_ALGOS: frozenset[str] = frozenset(ALGOS[2:])
"""Algorithms that learn the shaping weight z_phi (Hu et al. 2020)."""


class AdviceMode(StrEnum):
    """How F is made: the three of :class:`engine.advice.AdviceReward` (F from the advice
    tree), or ``reward`` (F = R; the advice tree is then only what the agent is compared
    against)."""

    NEAREST = "nearest"
    SOFTMAX = "softmax"
    PAPER_MIN = "paper-min"
    REWARD = "reward"


REWARD_ADVICE = AdviceMode.REWARD.value
"""The advice mode in which F is the env's own step reward (the paper's Case 1, F = R)."""

ADVICE_MODES: tuple[str, ...] = tuple(m.value for m in AdviceMode)
"""The values of :class:`AdviceMode`."""

MIN_MINIBATCH = 2
"""Fewest transitions per minibatch: advantages are normalised by their std over it, and the
std of one value is NaN (silently NaN training)."""


def _weights(given: Any) -> tuple[float, ...]:
    """``pool_weights`` as a tuple of floats; :class:`InputError` for anything but numbers."""
    if not isinstance(given, list | tuple) or not all(
        isinstance(w, int | float) and not isinstance(w, bool) for w in given
    ):
        raise InputError(f"pool weights must be a list of numbers, got {given!r}")
    return tuple(float(w) for w in given)


@dataclass(frozen=True)
class TrainConfig:
    """Everything that determines a training run (saved as the run's ``config.json``)."""

    algo: str = "ppo"
    """one of :data:`ALGOS`"""
    env_id: str = "Humanoid-v5"
    """Gymnasium MuJoCo env id"""
    total_timesteps: int = 1_000_000
    """env steps over all envs"""
    seed: int = 0
    """seed of torch, numpy and the envs"""
    n_envs: int = 4
    """parallel envs in one ``SyncVectorEnv``"""
    num_steps: int = 512
    """steps per env per rollout (batch = ``n_envs * num_steps``)"""
    num_minibatches: int = 32
    """minibatches per epoch"""
    update_epochs: int = 10
    """epochs over each rollout"""
    learning_rate: float = 3e-4
    """Adam learning rate of the policy and critics"""
    anneal_lr: bool = True
    """anneal the learning rates linearly to 0 over the run"""
    gamma: float = 0.99
    """discount factor"""
    gae_lambda: float = 0.95
    """GAE lambda"""
    clip_coef: float = 0.2
    """PPO surrogate clipping coefficient"""
    ent_coef: float = 0.0
    """entropy bonus coefficient"""
    vf_coef: float = 0.5
    """value loss coefficient"""
    max_grad_norm: float = 0.5
    """global gradient norm clip"""
    norm_obs: bool = True
    """normalise observations with running statistics"""
    norm_reward: bool = True
    """scale rewards by the running std of the discounted return"""
    hidden: int = 64
    """width of the two hidden layers of every network"""
    advice_scale: float = 1.0
    """multiplies F(s) before shaping"""
    advice_offset: float = 0.0
    """added to F(s) before ``advice_scale``: with F >= -offset (``nearest`` F is >= -r_b when
    the best similarity is >= 0 and the depth factor is ``none``), advice cannot be escaped by
    ending the episode early, which an env that terminates on falling (Hopper) otherwise pays
    for when F < 0 where the agent starts"""
    advice_mode: str = "nearest"
    """one of :data:`ADVICE_MODES`: how F is made from the advice tree, or ``reward`` (F = R)"""
    advice_depth_factor: str = "none"
    """depth factor D of F (none or paper)"""
    advice_kappa: float = 10.0
    """softmax temperature of the ``softmax`` F mode"""
    z_max: float = 2.0
    """z_phi(s) = z_max * tanh(.), so z lies in (-z_max, z_max)"""
    z_init: float = 1.0
    """z_phi(s) at initialisation (near this value for every state)"""
    z_learning_rate: float = 1e-3
    """Adam learning rate of z_phi"""
    z_epochs: int = 1
    """epochs of z_phi updates over each rollout (bipars-em)"""
    meta_lr: float = 0.1
    """inner step size of the one-step meta-gradient (bipars-mgl)"""
    checkpoint_every: int = 50_000
    """write ``checkpoints/step_<timesteps>.pt`` every this many env steps"""
    pool_weights: tuple[float, ...] | None = None
    """pooled advice: one weight per tree, in the pool's order (F and the pooled verdict are
    the weighted mean, :class:`engine.advice.PooledAdvice`); None: the plain mean"""

    def __post_init__(self) -> None:
        if self.pool_weights is not None:  # JSON gives a list; a frozen config keeps a tuple
            object.__setattr__(self, "pool_weights", _weights(self.pool_weights))
        errors = self._errors()
        if errors:
            raise InputError(errors[0])

    def _errors(self) -> list[str]:
        checks = [
            (self.algo in ALGOS, f"unknown algo {self.algo!r}: choose one of {', '.join(ALGOS)}"),
            (self.total_timesteps > 0, f"timesteps must be positive, got {self.total_timesteps}"),
            (seed_error(self.seed) is None, seed_error(self.seed) or ""),
            (self.n_envs >= 1 and self.num_steps >= 2, "n_envs must be >= 1, num_steps >= 2"),
            (self.num_minibatches >= 1, "num_minibatches must be >= 1"),
            (
                self.num_minibatches < 1 or self.minibatch_size >= MIN_MINIBATCH,
                self._minibatch_message(),
            ),
            (self.update_epochs >= 1 and self.z_epochs >= 1, "epochs must be >= 1"),
            (0 < self.gamma <= 1 and 0 <= self.gae_lambda <= 1, "gamma/gae_lambda out of range"),
            (self.learning_rate > 0 and self.z_learning_rate > 0, "learning rates must be > 0"),
            (self.checkpoint_every > 0, "checkpoint-every must be positive"),
            (0 < abs(self.z_init) < self.z_max, "z_init must satisfy 0 < |z_init| < z_max"),
            (
                0 < self.advice_scale < math.inf,
                f"advice-scale must be a positive finite number, got {self.advice_scale}",
            ),
            (
                0 <= self.advice_offset <= 100,
                f"advice-offset must be in [0, 100], got {self.advice_offset}",
            ),
            *self._advice_checks(),
            (
                self._pool_weights_ok(),
                "pool weights must be two or more numbers, finite, >= 0, and not all 0",
            ),
        ]
        return [message for ok, message in checks if not ok]

    def _pool_weights_ok(self) -> bool:
        w = self.pool_weights
        return w is None or (
            all(math.isfinite(x) and x >= 0 for x in w) and sum(w) > 0 and len(w) >= 2
        )

    def _advice_checks(self) -> list[tuple[bool, str]]:
        # deferred: engine.advice loads mujoco and gymnasium; this module stays light
        from engine.advice import DEPTH_FACTORS

        return [
            (
                self.advice_mode in ADVICE_MODES,
                f"unknown advice mode {self.advice_mode!r}: "
                f"choose one of {', '.join(ADVICE_MODES)}",
            ),
            (
                self.advice_depth_factor in DEPTH_FACTORS,
                f"unknown advice depth factor {self.advice_depth_factor!r}: choose one of "
                f"{', '.join(DEPTH_FACTORS)}",
            ),
            (
                math.isfinite(self.advice_kappa) and self.advice_kappa > 0,
                f"advice kappa must be a positive number, got {self.advice_kappa}",
            ),
        ]

    def _minibatch_message(self) -> str:
        # the CLI has no --num-minibatches: name the options it does have
        n = max(self.num_minibatches, 1)
        return (
            f"a rollout of n_envs x num_steps = {self.n_envs} x {self.num_steps} = "
            f"{self.batch_size} transitions split into num_minibatches = {n} leaves "
            f"{self.batch_size // n} per minibatch (at least {MIN_MINIBATCH} needed): raise "
            f"--n-envs or --num-steps so that n-envs x num-steps >= {MIN_MINIBATCH * n}, "
            "or lower num_minibatches where it can be set"
        )

    @property
    def batch_size(self) -> int:
        """Transitions per rollout."""
        return self.n_envs * self.num_steps

    @property
    def minibatch_size(self) -> int:
        """Transitions per gradient step."""
        return self.batch_size // self.num_minibatches

    @property
    def num_updates(self) -> int:
        """Rollouts in the run (the last one may overshoot ``total_timesteps``)."""
        return -(-self.total_timesteps // self.batch_size)

    @property
    def uses_advice(self) -> bool:
        """Whether the algorithm shapes the reward with F."""
        return self.algo in ADVISED_ALGOS

    @property
    def learns_z(self) -> bool:
        """Whether the algorithm learns z_phi."""
        return self.algo in BIPARS_ALGOS

    def tree_options(self) -> dict[str, Any]:
        """F's options for a tree of this run (the pooled verdict): ``nearest`` when F = R,
        which has none of its own."""
        mode = "nearest" if self.advice_mode == REWARD_ADVICE else self.advice_mode
        return {"mode": mode, "depth_factor": self.advice_depth_factor, "kappa": self.advice_kappa}

    def to_json(self) -> dict[str, Any]:
        """Plain dict for ``config.json``; ``pool_weights`` only when set, so that a config
        without them is the same dict as before they existed (runs are reused by config)."""
        out = dataclasses.asdict(self)
        weights = out.pop("pool_weights")
        return out if weights is None else out | {"pool_weights": list(weights)}

    @classmethod
    def from_json(cls, obj: Any) -> TrainConfig:
        """Inverse of :meth:`to_json`; unknown or missing keys raise :class:`InputError`."""
        if not isinstance(obj, dict):
            raise InputError("config must be a JSON object")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(obj) - names)
        if unknown:
            raise InputError(f"unknown config keys: {', '.join(unknown)}")
        try:
            return cls(**obj)
        except TypeError as exc:
            raise InputError(f"invalid config: {exc}") from exc
