"""The advisor's bracket as a reminder (issue 41: "A reminder of the advisor's bracket is an
option, off by default and recorded with every answer. Showing it measures 'followed your
tree' again.").

When an advisor evaluation has ``show_bracket``, each of its pairs shows, folded away, the
top of the advisor's own finished bracket: the picture they chose in the final, then the
final's other picture, then those the semi-finals' winners beat (at most :data:`PLACES`),
from the bracket of the participant whose tree trained the advised runs. The pictures are
served under their place's name (``/api/evaluators/me/reminder/first`` ...), never a number,
candidate,
study, run or arm. Whether it was shown is stored with every answer
(``evaluation_pairs.reminder``): it is shown whenever it is on and the advisor's bracket is
there to show.
"""

from __future__ import annotations

from sqlalchemy.orm import Session

from app.labelling.service import bracket_view
from app.models import Candidate, Evaluation, Participant

#: The reminder's places, best first, as its pictures' URLs name them (words: a number in
#: an evaluator's URL could read as a run id).
PLACES = ("first", "second", "third", "fourth")
#: What the reminder says it is (the pair page shows it with the pictures).
TEXT = (
    "A reminder of your own earlier choices: the pictures you ranked highest in your "
    "bracket, your choice in the final first. They are not the agents, and you may answer "
    "without looking at them."
)
#: What each place's picture is, for its text alternative.
PLACE_NAMES = (
    "your choice in the final",
    "the other picture of your final",
    "a picture from one of your semi-finals",
    "a picture from one of your semi-finals",
)


def ranked(session: Session, advisor: Participant) -> list[int]:
    """The advisor's bracket's top candidate ids, best first: the final's winner, its other
    player, then the earlier rounds' losers, latest round first (empty while unfinished)."""
    rounds = bracket_view(session, participant=advisor)
    if not rounds or rounds[-1][0].winner is None:
        return []
    found = [rounds[-1][0].winner]
    for cells in reversed(rounds):
        for cell in cells:
            if cell.is_bye or cell.winner is None:
                continue
            found.append(cell.b if cell.winner == cell.a else cell.a)  # type: ignore[arg-type]
        if len(found) >= len(PLACES):
            break
    return [c for c in found if c is not None][: len(PLACES)]


def pictures(session: Session, evaluation: Evaluation) -> list[Candidate]:
    """The reminder's candidates, best first: empty when the evaluation has no reminder, no
    advisor (any more), or the advisor's bracket is unfinished."""
    if not evaluation.show_bracket or evaluation.advisor_id is None:
        return []
    advisor = session.get(Participant, evaluation.advisor_id)
    if advisor is None:
        return []
    ids = ranked(session, advisor)
    found = [session.get(Candidate, (advisor.study_id, c)) for c in ids]
    return [c for c in found if c is not None]


def shown(session: Session, evaluation: Evaluation) -> bool:
    """Whether the evaluation's pair pages show the reminder (stored with each answer)."""
    return bool(pictures(session, evaluation))


def urls(session: Session, evaluation: Evaluation) -> list[dict[str, str]] | None:
    """The reminder as a pair shows it: each picture's URL (by place) and what it is;
    ``None`` when none is shown."""
    found = pictures(session, evaluation)
    if not found:
        return None
    return [
        {"url": f"/api/evaluators/me/reminder/{PLACES[i]}", "alt": PLACE_NAMES[i]}
        for i in range(len(found))
    ]
