"""The acv.tree/1 document: round trip, determinism, and rejection of anything else."""

from __future__ import annotations

import copy
import json

import pytest

from engine.conformance import compare
from engine.errors import InputError
from engine.pipeline import run_tournament
from engine.treefile import dumps, load_tree, make_document, tree_from_json, tree_to_json


@pytest.fixture(scope="module")
def doc():
    return run_tournament(env_id="Hopper-v5", n_candidates=6, p=0.9, seed=5, teacher="good")


def test_round_trip_is_byte_identical(doc) -> None:
    text = dumps(doc)
    assert dumps(tree_from_json(json.loads(text))) == text


def test_same_seed_same_bytes(doc) -> None:
    again = run_tournament(env_id="Hopper-v5", n_candidates=6, p=0.9, seed=5, teacher="good")
    assert dumps(again) == dumps(doc)


def test_document_has_the_documented_keys(doc) -> None:
    obj = tree_to_json(doc)
    assert obj["schema"] == "acv.tree/1"
    assert set(obj) == {
        "schema",
        "env_id",
        "seed",
        "p",
        "judge",
        "tree_reward",
        "candidates",
        "first_round",
        "matches",
        "tree",
    }
    assert len(obj["matches"]) == 5 and len(obj["tree"]["nodes"]) == 6
    assert {"id", "qpos", "qvel", "env_reward"} <= set(obj["candidates"][0])
    assert set(obj["tree"]["nodes"][0]) == {
        "state",
        "parent",
        "height",
        "depth",
        "weight",
        "reward",
    }


def _tamper_winner(obj):
    m = obj["matches"][0]
    m["winner"] = m["a"] if m["winner"] == m["b"] else m["b"]


def _tamper_height(obj):
    obj["tree"]["nodes"][1]["height"] += 1


@pytest.mark.parametrize(
    "tamper",
    [
        lambda o: o.update(schema="acv.tree/0"),
        lambda o: o.pop("matches"),
        lambda o: o["matches"].pop(),
        lambda o: o["matches"].append(dict(o["matches"][0])),
        lambda o: o["candidates"][0].update(qpos="x"),
        lambda o: o["candidates"][0].update(id=9),
        lambda o: o["first_round"].pop(),
        _tamper_winner,
        _tamper_height,
    ],
    ids=[
        "schema",
        "no-matches",
        "missing-match",
        "duplicate-match",
        "bad-qpos",
        "bad-id",
        "short-first-round",
        "winner",
        "height",
    ],
)
def test_invalid_documents_are_rejected(doc, tamper) -> None:
    obj = copy.deepcopy(tree_to_json(doc))
    tamper(obj)
    with pytest.raises(InputError):
        tree_from_json(obj)


@pytest.mark.parametrize("content", [b"not json", b"[1, 2]", b"\xff\xfe\x00"])
def test_load_rejects_non_documents(tmp_path, content: bytes) -> None:
    path = tmp_path / "x.json"
    path.write_bytes(content)
    with pytest.raises(InputError):
        load_tree(path)


def test_load_missing_file(tmp_path) -> None:
    with pytest.raises(InputError):
        load_tree(tmp_path / "nope.json")


def _node(obj, **changes):
    obj["tree"]["nodes"][0].update(changes)


@pytest.mark.parametrize(
    ("tamper", "words"),
    [
        (lambda o: o.pop("tree"), "missing key 'tree'"),
        (lambda o: o["tree"].pop("nodes"), "'nodes' list"),
        (lambda o: _node(o, state=[0]), "does not match"),
        (lambda o: _node(o, reward="a lot"), "does not match"),
        (lambda o: _node(o, reward=None), "does not match"),
        (lambda o: o.update(seed=-1), "seed must be in 0"),
        (lambda o: o.update(seed=float("inf")), "OverflowError"),
        (lambda o: o.update(p=1.5), "'p' must be in [0, 1]"),
        (lambda o: o["tree_reward"].update(r_b=[1]), "TypeError"),
    ],
    ids=[
        "no-tree",
        "no-nodes",
        "list-state",
        "text-reward",
        "null-reward",
        "negative-seed",
        "infinite-seed",
        "p",
        "list-r_b",
    ],
)
def test_malformed_documents_are_one_clear_input_error(doc, tamper, words: str) -> None:
    obj = copy.deepcopy(tree_to_json(doc))
    tamper(obj)
    with pytest.raises(InputError) as info:
        tree_from_json(obj)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_a_one_candidate_tree_is_rejected(doc) -> None:
    lone = make_document(
        env_id=doc.env_id,
        seed=doc.seed,
        p=doc.p,
        judge=doc.judge,
        candidates=doc.candidates[:1],
        first_round=[(0, None)],
        results={},
    )
    assert len(lone.tree) == 1  # the engine can build it, but there is nothing to compare
    obj = tree_to_json(lone)
    with pytest.raises(InputError, match="at least 2 candidates"):
        tree_from_json(obj)
    with pytest.raises(InputError, match="no matches"):
        compare(lone, lone)


def test_load_reports_the_file_of_a_malformed_tree(doc, tmp_path) -> None:
    obj = tree_to_json(doc)
    obj["tree"]["nodes"][0]["reward"] = "high"
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(obj))
    with pytest.raises(InputError, match="bad.json"):
        load_tree(path)


def test_a_negative_seed_is_an_input_error() -> None:
    with pytest.raises(InputError, match="seed must be in 0"):
        run_tournament(env_id="Hopper-v5", n_candidates=4, p=0.9, seed=-1, teacher="good")


@pytest.mark.parametrize("number", [float("nan"), float("inf"), float("-inf")])
@pytest.mark.parametrize(
    "put",
    [
        lambda o, x: o["candidates"][0].update(env_reward=x),
        lambda o, x: (
            [c.update(score=1.0) for c in o["candidates"]] and o["candidates"][1].update(score=x)
        ),
        lambda o, x: o["tree_reward"].update(r_b=x),
        lambda o, x: o["tree_reward"].update(r_e=x),
        lambda o, x: o.update(p=x),
        lambda o, x: o["candidates"][0]["qvel"].__setitem__(0, x),
        lambda o, x: _node(o, reward=x),
    ],
    ids=["env_reward", "score", "r_b", "r_e", "p", "qvel", "node-reward"],
)
def test_every_number_must_be_finite(doc, put, number: float) -> None:
    obj = copy.deepcopy(tree_to_json(doc))
    put(obj, number)
    with pytest.raises(InputError) as info:
        tree_from_json(obj)
    assert "\n" not in str(info.value)
