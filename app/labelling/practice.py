"""Practice before the bracket (issue 28 §3): a participant's practice pairs, their pictures
and the feedback on an answer. Nothing of practice is stored.

A study with ``practice_pairs = k`` (2 to 5) shows each participant ``k`` practice pairs after
the instructions and before their first match, on practice states that are not among the
study's candidates (:mod:`app.studies.practice_states`), so practice cannot prime the
bracket. About half of the pairs are *instructed* ("choose the picture with the marker"): the
answer is right or wrong and the feedback says which. The others are plain preference pairs:
the feedback only says that there is no right answer, in practice or in the study's real
pairs. Which pairs, in which order and on which sides is seeded by the study's seed and the
participant's id (:func:`engine.practice.practice_plan`), so a reload shows the same pair.
Answers are not stored (no label, no match); a participant who has a label never sees
practice again.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.labelling.participants import ParticipantKey, progress
from app.studies.practice_states import PracticeStates, practice_states
from app.studies.service import get_study
from engine.errors import InputError
from engine.practice import SIDES, PairKind, PracticePair, Side, practice_plan

#: What each kind of pair asks.
PROMPTS: dict[PairKind, str] = {
    "instructed": "Choose the picture with the marker (a ring in its top-left corner).",
    "preference": "Which picture do you prefer?",
}
NO_RIGHT_ANSWER = (
    "There is no right answer here, and there is none in the study's real pairs either: "
    "there, pick the picture you prefer."
)


@dataclass(frozen=True)
class Practice:
    """A participant's practice: its pairs in order, on the study's stored states."""

    pairs: list[PracticePair]
    states: PracticeStates | None

    def pair(self, position: int) -> PracticePair:
        """Pair ``position`` (from 0), or :class:`NotFoundError`."""
        if not 0 <= position < len(self.pairs):
            raise NotFoundError(
                f"there is no practice pair {position} for this participant: they have "
                f"{len(self.pairs)} (none once they have started their bracket)"
            )
        return self.pairs[position]


@dataclass(frozen=True)
class Feedback:
    """What an answer to a practice pair gets: right or wrong (None: there is no right
    answer), where the marker was (instructed pairs), and a sentence for the participant."""

    correct: bool | None
    marker: Side | None
    message: str


def practice(session: Session, *, participant: ParticipantKey, images_dir: Path) -> Practice:
    """The participant's practice; no pairs when the study asks none, once they have a label,
    or when the study's practice states are missing on disk (logged)."""
    study = get_study(session, study_id=participant.study_id)
    if study.practice_pairs == 0 or progress(session, participant=participant).done > 0:
        return Practice([], None)
    states = practice_states(images_dir, study)
    if states is None:
        return Practice([], None)
    plan = practice_plan(study.practice_pairs, seed=study.seed, participant_id=participant.id)
    return Practice(plan, states)


def picture(found: Practice, *, position: int, side: str) -> Path:
    """The picture shown on ``side`` of pair ``position`` (with the marker where it has it).

    Raises:
        NotFoundError: no such pair, or its picture is missing on disk.
        InputError: ``side`` is neither ``left`` nor ``right``.
    """
    pair, chosen = found.pair(position), check_side(side)
    assert found.states is not None  # a practice with pairs has its states
    state = pair.left if chosen == "left" else pair.right
    path = found.states.image(state, marked=pair.is_marked(chosen))
    if not path.is_file():
        raise NotFoundError(f"the picture of practice pair {position} is missing on disk")
    return path


def feedback(pair: PracticePair, side: str) -> Feedback:
    """The feedback on choosing ``side`` of ``pair`` (stores nothing).

    Raises:
        InputError: ``side`` is neither ``left`` nor ``right``.
    """
    correct = pair.correct(check_side(side))
    if pair.marked is None:
        return Feedback(None, None, NO_RIGHT_ANSWER)
    verdict = "Right" if correct else "Not quite"
    return Feedback(correct, pair.marked, f"{verdict}: the marker was on the {pair.marked}.")


def check_side(side: str) -> Side:
    """``side`` if it is ``left`` or ``right``; else :class:`InputError`."""
    for known in SIDES:
        if side == known:
            return known
    raise InputError(f"side must be left or right, got {side[:20]!r}")
