"""What another request does between a read and a write: made deterministic by running that
other request exactly there (a patched step of the service), never by hoping threads meet."""

from __future__ import annotations

from typing import Any

from app.labelling import check
from app.models import ConsistencyCheck, Participant
from app.recruiting import service as recruiting
from tests.support.crowd import configure, joined_player, visit


def test_a_link_made_meanwhile_takes_the_options(client, make_study, monkeypatch) -> None:
    """Two first saves at once: the one whose read missed the other's link meets it at the
    unique index and updates it (this was a 500)."""
    study = make_study()
    first = configure(client, study["id"])
    real, missed = recruiting.settings, []

    def read_before_the_other_committed(*args: Any, for_update: bool = False) -> Any:
        if for_update and not missed:
            missed.append(args[-1])
            return None
        return real(*args, for_update=for_update)

    monkeypatch.setattr(recruiting, "settings", read_before_the_other_committed)
    second = configure(client, study["id"], max_participants=7)
    assert missed == [study["id"]]
    assert second["slug"] == first["slug"] and second["max_participants"] == 7


def test_a_check_answered_meanwhile_is_not_overwritten(client, make_study, monkeypatch) -> None:
    """The consistency check's answer is read again under the write lock: a second answer
    the other way, sent while the first was being stored, is a 409 and the first is kept."""
    study = make_study(n_candidates=4, seed=2)
    link = configure(client, study["id"], consistency_check=True)
    browser, response = visit(client, link)
    player = joined_player(client, browser, response)
    while (match := player.next_match()) is not None:
        assert player.label(match["match_id"], match["left"], response_ms=500).status_code == 201
    page = browser.get("/participate/check")
    pair = [int(v) for v in _buttons(page.text)]
    csrf = page.text.split('name="csrf_token" value="')[1].split('"')[0]
    sessions = client.app.state.runtime.sessions
    real = check.check_stimulus

    def other_answer_first(*args: Any) -> None:
        monkeypatch.setattr(check, "check_stimulus", real)
        with sessions() as other:  # the other request, stored before this one writes
            person = other.get_one(Participant, player.id)
            check.answer(other, participant=person, winner=pair[0])
        real(*args)

    monkeypatch.setattr(check, "check_stimulus", other_answer_first)
    late = browser.post("/participate/check", data={"csrf_token": csrf, "winner": str(pair[1])})
    assert late.status_code == 409, late.text
    with sessions() as session:
        assert session.get_one(ConsistencyCheck, player.id).winner == pair[0]


def _buttons(html: str) -> list[str]:
    """The two candidates the check's form offers, left then right."""
    return [part.split('"')[0] for part in html.split('name="winner" value="')[1:3]]
