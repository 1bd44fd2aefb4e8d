"""The validation's design, fixed before any run (docs/validation.md §2).

Every arm trains on the same env, budget and evaluation seeds; only what it is told differs:

- negative controls: ``n1`` (``ppo``, no advice), ``n2-1`` and ``n2-10`` (``ppo-shaped`` on
  *shuffled* advice, the `random` teacher on the same bracket, at scales 1 and 10: any shaping
  term of that size), ``n3`` (``ppo-shaped`` on *inverted* advice, score 1 - s, scale 3: the
  verdict must be able to see rejection);
- positive controls ``p1-1``, ``p1-3``, ``p1-10``: ``ppo-shaped`` on the advice at scale
  λ ∈ {1, 3, 10}, a dose response;
- subjects ``bipars-em`` and ``bipars-mgl`` at λ = 1.

Seeds never overlap across uses: evaluation seeds ``0 .. seeds-1`` train the arms; pilot seeds
(:data:`PILOT_SEED0` on) train the no-advice pilots that sample the candidates and pick the
contested matches; brackets draw from :data:`BRACKET_SEED0` on; the ground truth resets
from :data:`TRUTH_RESET_SEED0` on, apart from the behaviour judge's resets (0 on).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from enum import StrEnum
from typing import Any, Protocol

from engine.errors import InputError
from engine.teachers import POSTURE_SCORES

PILOT_SEED0 = 1000
BRACKET_SEED0 = 20_000
TRUTH_RESET_SEED0 = 10_000


class AdviceKind(StrEnum):
    """What an arm trains on: nothing, the advice, or one of its controls."""

    NONE = "none"
    ADVICE = "advice"
    SHUFFLED = "shuffled"
    INVERTED = "inverted"
    NOISY = "noisy"
    STANDING_SHUFFLED = "standing-shuffled"


class Role(StrEnum):
    """An arm's part: the verdict must not find the advice in a negative control, must find
    it in a positive one, and is what the researcher asks about for a subject."""

    NEGATIVE = "negative"
    POSITIVE = "positive"
    SUBJECT = "subject"


@dataclass(frozen=True)
class Arm:
    """One arm: an algorithm, what it trains on and at which scale of F."""

    name: str
    algo: str
    advice: AdviceKind
    scale: float
    role: Role


ARMS: tuple[Arm, ...] = (
    Arm("n1", "ppo", AdviceKind.NONE, 0.0, Role.NEGATIVE),
    Arm("n2-1", "ppo-shaped", AdviceKind.SHUFFLED, 1.0, Role.NEGATIVE),
    Arm("n2-10", "ppo-shaped", AdviceKind.SHUFFLED, 10.0, Role.NEGATIVE),
    Arm("n3", "ppo-shaped", AdviceKind.INVERTED, 3.0, Role.NEGATIVE),
    Arm("p1-1", "ppo-shaped", AdviceKind.ADVICE, 1.0, Role.POSITIVE),
    Arm("p1-3", "ppo-shaped", AdviceKind.ADVICE, 3.0, Role.POSITIVE),
    Arm("p1-10", "ppo-shaped", AdviceKind.ADVICE, 10.0, Role.POSITIVE),
    Arm("bipars-em", "bipars-em", AdviceKind.ADVICE, 1.0, Role.SUBJECT),
    Arm("bipars-mgl", "bipars-mgl", AdviceKind.ADVICE, 1.0, Role.SUBJECT),
)
BASELINE = "n1"
PILOT = Arm("pilot", "ppo", AdviceKind.NONE, 0.0, Role.NEGATIVE)
ARM_BY_NAME = {arm.name: arm for arm in (*ARMS, PILOT)}


class TrainingPlan(Protocol):
    """What a validation's runs train with (round 1's :class:`Plan` and round 2's)."""

    @property
    def env_id(self) -> str: ...
    @property
    def timesteps(self) -> int: ...
    @property
    def n_envs(self) -> int: ...
    @property
    def num_steps(self) -> int: ...


class BracketPlan(Protocol):
    """What a validation's brackets are drawn with."""

    @property
    def env_id(self) -> str: ...
    @property
    def teacher(self) -> str: ...
    @property
    def candidates(self) -> int: ...
    @property
    def p(self) -> float: ...


@dataclass(frozen=True)
class Plan:
    """One validation: what every arm trains on, saved as ``validate.json`` and checked on
    resume (a changed plan is a new validation, in a new folder)."""

    env_id: str
    teacher: str
    timesteps: int
    seeds: int = 8
    """Evaluation seeds per arm: ``0 .. seeds-1``."""
    pilot_seeds: int = 2
    """No-advice pilots on seeds of their own: they sample candidates and pick matches."""
    brackets: int = 5
    """Evaluation brackets; bracket 0's tree is also the advice every arm trains on."""
    candidates: int = 16
    """Candidate states per bracket, sampled in the ``informative`` mode."""
    p: float = 0.9
    """Braverman-Mossel coin probability of every bracket."""
    n_envs: int = 4
    num_steps: int = 512
    truth_episodes: int = 5
    """Deterministic episodes of the ground truth per run."""
    arms: tuple[str, ...] = tuple(arm.name for arm in ARMS)
    """The arms trained (``n1`` always); a subset for a smaller validation."""

    def __post_init__(self) -> None:
        for name in ("timesteps", "seeds", "pilot_seeds", "brackets", "truth_episodes"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} must be at least 1, got {getattr(self, name)}")
        if self.candidates < 4:
            raise InputError(f"candidates must be at least 4, got {self.candidates}")
        if self.teacher not in POSTURE_SCORES:
            raise InputError(
                f"the teacher must have a posture score, the ground truth: "
                f"{' or '.join(POSTURE_SCORES)}, got {self.teacher!r}"
            )
        if self.seeds + self.n_envs > PILOT_SEED0:  # env k of seed s resets with seed s + k
            raise InputError(f"seeds + n_envs must be at most {PILOT_SEED0} (the pilots' seeds)")
        self._check_arms()
        # one order whatever order they were given in, so that a resume finds the same plan
        object.__setattr__(self, "arms", tuple(a.name for a in ARMS if a.name in self.arms))

    def _check_arms(self) -> None:
        unknown = sorted(set(self.arms) - {arm.name for arm in ARMS})
        if unknown or BASELINE not in self.arms or len(set(self.arms)) < 2:
            raise InputError(
                f"arms must include {BASELINE} and another arm, and name only "
                f"{', '.join(a.name for a in ARMS)}"
                + (f": unknown {', '.join(unknown)}" if unknown else "")
            )

    @property
    def chosen(self) -> tuple[Arm, ...]:
        """The arms trained, in :data:`ARMS` order."""
        return tuple(arm for arm in ARMS if arm.name in self.arms)

    def pilot_seed_list(self) -> list[int]:
        return [PILOT_SEED0 + k for k in range(self.pilot_seeds)]

    def to_json(self) -> dict[str, Any]:
        return asdict(self) | {"arms": list(self.arms)}

    @classmethod
    def from_json(cls, obj: dict[str, Any]) -> Plan:
        """The plan of a ``validate.json`` (keys of other versions dropped, defaults filled)."""
        known = {f.name for f in fields(cls)} & set(obj)
        found = {k: obj[k] for k in known}
        return cls(**found | ({"arms": tuple(obj["arms"])} if "arms" in obj else {}))
