"""Every integer field of every JSON request body refuses what is not a JSON integer.

The fields are found in the OpenAPI schema (nested objects, arrays, maps and tagged unions
included), so a new body is covered without editing this file. Each gets ``true``,
``false``, ``3.0``, ``1.0``, ``1.5`` and ``"1"``; the answer must be a 422 whose JSON names
the field (lax parsing would read ``true`` as 1, ``"1"`` and ``1.0`` as 1, and ``1.5`` as 1
after rounding).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.support.openapi import api_openapi, json_operations
from tests.support.surveys import scheme_headers

#: The house rule: a JSON ``false`` is not an integer, nor is ``3.0`` (a float that happens
#: to be whole), nor the text ``"1"``.
BAD_INTEGERS = (True, False, 3.0, 1.0, 1.5, "1")
#: Refs nested deeper than this are free-form documents (``doc``), not body fields.
MAX_DEPTH = 8


@dataclass(frozen=True)
class IntegerField:
    """An integer field of one operation's JSON body, and how to put a value there."""

    method: str
    path: str
    names: tuple[str, ...]  # "[]" an array item, "*" a map value
    build: Callable[[Any], Any]  # a body holding the value at the field
    scheme: str  # the security scheme whose credentials the operation takes

    def __str__(self) -> str:
        return f"{self.method} {self.path} {'.'.join(self.names)}"


def _integer_fields(
    schema: dict[str, Any], components: dict[str, Any], depth: int = 0
) -> Iterator[tuple[tuple[str, ...], Callable[[Any], Any]]]:
    """(names, build) of every integer in ``schema``; ``build(v)`` is the smallest JSON with
    ``v`` there and every constant (a tagged union's tag) beside it, so validation reaches
    the field."""
    if "$ref" in schema:
        schema = components[schema["$ref"].rsplit("/", 1)[-1]]
    if depth > MAX_DEPTH:
        return
    for key in ("anyOf", "oneOf", "allOf"):
        for option in schema.get(key, []):
            yield from _integer_fields(option, components, depth + 1)
    types = schema.get("type")
    if types == "integer" or (isinstance(types, list) and "integer" in types):
        yield (), lambda value: value
    yield from _object_fields(schema, components, depth)
    if isinstance(items := schema.get("items"), dict):
        for names, build in _integer_fields(items, components, depth + 1):
            yield ("[]", *names), lambda value, b=build: [b(value)]
    if isinstance(values := schema.get("additionalProperties"), dict):
        for names, build in _integer_fields(values, components, depth + 1):
            yield ("*", *names), lambda value, b=build: {"key": b(value)}


def _object_fields(
    schema: dict[str, Any], components: dict[str, Any], depth: int
) -> Iterator[tuple[tuple[str, ...], Callable[[Any], Any]]]:
    properties = schema.get("properties", {})
    constants = {name: p["const"] for name, p in properties.items() if "const" in p}
    for name, prop in properties.items():
        for names, build in _integer_fields(prop, components, depth + 1):
            yield (name, *names), lambda value, n=name, b=build: constants | {n: b(value)}


def discover(openapi: dict[str, Any]) -> list[IntegerField]:
    """Every integer field of every ``application/json`` request body of ``openapi``."""
    components = openapi.get("components", {}).get("schemas", {})
    found = []
    for op in json_operations(openapi):
        [scheme] = op.schemes
        found += [
            IntegerField(op.method, op.path, names, build, scheme)
            for names, build in _integer_fields(op.schema, components)
        ]
    return found


FIELDS = discover(api_openapi())


def test_the_discovered_fields_are_those_the_app_serves(client) -> None:
    served = discover(client.get("/openapi.json").json())
    assert sorted(map(str, served)) == sorted(map(str, FIELDS))
    assert {
        "POST /api/studies seed",
        "POST /api/runs seed",
        "POST /api/surveys stimuli.[].tree1.participant_id",
        "POST /api/surveys/me/screens/{position}/answers answers.*.confidence",
    } <= set(map(str, FIELDS))


@pytest.fixture(scope="module")
def credentials(client: TestClient, study: dict[str, Any]) -> dict[str, dict[str, str]]:
    return scheme_headers(client, study["id"])


@pytest.mark.parametrize("bad", BAD_INTEGERS, ids=repr)
@pytest.mark.parametrize("field", FIELDS, ids=str)
def test_integer_fields_refuse_what_is_not_an_integer(
    client, credentials, field: IntegerField, bad: Any
) -> None:
    url = re.sub(r"\{[^}]+\}", "1", field.path)
    response = client.request(
        field.method, url, headers=credentials[field.scheme], json=field.build(bad)
    )
    assert response.status_code == 422, response.text
    name = [n for n in field.names if n not in ("[]", "*")][-1]
    named = [
        e
        for e in response.json()["detail"]
        # an array item's loc ends in its index: the field is the last name before it
        if e["loc"][0] == "body"
        and [n for n in e["loc"] if not isinstance(n, int)][-1] == name
        and e["type"] != "missing"
    ]
    assert named, response.text
