"""One integer rule, everywhere, and an OpenAPI document that states it (issue 45 §6), on
PostgreSQL (the values are refused before any database sees them).

Every rule is checked by walking the OpenAPI document, so a new body, field or parameter is
covered without editing this file:

- every integer field of every JSON request body (nested objects, arrays, maps and tagged
  unions included) refuses ``true``, ``false``, ``3.0``, ``1.0``, ``1.5`` and ``"1"``; lax
  parsing would read ``true`` as 1, ``"1"`` and ``1.0`` as 1, and ``1.5`` as 1;
- every number field (integers too) refuses ``true``/``false`` and the non-finite values
  Python's JSON reader accepts (``NaN``, ``Infinity``, ``-Infinity``, ``1e999``);
- every integer path and query parameter refuses ``1_0`` (lax: 10), ``1.0``, ``01``, ``+1``,
  `` 1`` and other text that is not plain decimal digits, and accepts its minimum;
- no schema holds ``ge``/``le``/``gt``/``lt`` (not JSON Schema: clients and fuzzers would see
  no bounds); bounds are ``minimum``/``maximum``/``exclusiveMinimum``/``exclusiveMaximum``.

Each refusal is a 422 whose JSON names the field or parameter. Every integer parameter of
every route, pages included, is an :class:`~app.core.json_types.IntParam`.
"""

from __future__ import annotations

import json
import re
import types
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Annotated, Any, Union, get_args, get_origin
from urllib.parse import quote

import pytest
from fastapi.routing import iter_route_contexts
from fastapi.testclient import TestClient

from app.core.json_types import IntParam
from tests.support.openapi import api_openapi, json_operations
from tests.support.surveys import scheme_headers

# postgres_only: a sweep of every route: validation and authorization are its subject, not storage.
pytestmark = pytest.mark.postgres_only

#: The house rule: a JSON ``false`` is not an integer, nor is ``3.0`` (a float that happens
#: to be whole), nor the text ``"1"``.
BAD_INTEGERS = (True, False, 3.0, 1.0, 1.5, "1")
#: Not a number, though Python's ``json`` reads each (``1e999`` as infinity).
NON_FINITE = ("NaN", "Infinity", "-Infinity", "1e999")
#: Text that lax parsing reads as an integer, or that is not plain decimal digits.
BAD_PARAMS = ("1_0", "1.0", "01", "+1", " 1", "1 ", "0x1", "1e1", "-0", "\u0661", "true")
#: Not JSON Schema keywords: pydantic writes its own names for bounds it cannot place.
NOT_KEYWORDS = frozenset({"ge", "le", "gt", "lt"})
#: Refs nested deeper than this are free-form documents (``doc``), not body fields.
MAX_DEPTH = 8
Build = Callable[[Any], Any]


@dataclass(frozen=True)
class NumberField:
    """An integer or number field of one operation's JSON body, and how to put a value
    there."""

    method: str
    path: str
    names: tuple[str, ...]  # "[]" an array item, "*" a map value
    build: Build  # a body holding the value at the field
    scheme: str  # the security scheme whose credentials the operation takes
    kind: str  # "integer" or "number"

    def __str__(self) -> str:
        return f"{self.method} {self.path} {'.'.join(self.names)}"


def _number_fields(
    schema: dict[str, Any], components: dict[str, Any], depth: int = 0
) -> Iterator[tuple[str, tuple[str, ...], Build]]:
    """(kind, names, build) of every integer and number in ``schema``; ``build(v)`` is the
    smallest JSON with ``v`` there and every constant (a tagged union's tag) beside it, so
    validation reaches the field."""
    if "$ref" in schema:
        schema = components[schema["$ref"].rsplit("/", 1)[-1]]
    if depth > MAX_DEPTH:
        return
    for key in ("anyOf", "oneOf", "allOf"):
        for option in schema.get(key, []):
            yield from _number_fields(option, components, depth + 1)
    types_ = schema.get("type")
    for kind in ("integer", "number"):
        if types_ == kind or (isinstance(types_, list) and kind in types_):
            yield kind, (), lambda value: value
    properties = schema.get("properties", {})
    constants = {name: p["const"] for name, p in properties.items() if "const" in p}
    for name, prop in properties.items():
        for kind, names, build in _number_fields(prop, components, depth + 1):
            yield kind, (name, *names), lambda v, n=name, b=build: constants | {n: b(v)}
    if isinstance(items := schema.get("items"), dict):
        for kind, names, build in _number_fields(items, components, depth + 1):
            yield kind, ("[]", *names), lambda value, b=build: [b(value)]
    if isinstance(values := schema.get("additionalProperties"), dict):
        for kind, names, build in _number_fields(values, components, depth + 1):
            yield kind, ("*", *names), lambda value, b=build: {"key": b(value)}


def discover(openapi: dict[str, Any]) -> list[NumberField]:
    """Every integer and number field of every ``application/json`` request body."""
    components = openapi.get("components", {}).get("schemas", {})
    found = []
    for op in json_operations(openapi):
        [scheme] = op.schemes
        found += [
            NumberField(op.method, op.path, names, build, scheme, kind)
            for kind, names, build in _number_fields(op.schema, components)
        ]
    return found


@dataclass(frozen=True)
class IntegerParam:
    """An integer path or query parameter of one operation."""

    method: str
    path: str
    where: str  # "path" or "query"
    name: str
    minimum: int
    scheme: str | None  # the security scheme whose credentials the operation takes

    def __str__(self) -> str:
        return f"{self.method} {self.path} {self.where}:{self.name}"

    def request(self, value: str) -> tuple[str, dict[str, str]]:
        """The URL and query with ``value`` here, and ``1`` in every other path parameter."""
        if self.where == "query":
            return re.sub(r"\{[^}]+\}", "1", self.path), {self.name: value}
        path = self.path.replace(f"{{{self.name}}}", quote(value, safe=""))
        return re.sub(r"\{[^}]+\}", "1", path), {}


def discover_params(openapi: dict[str, Any]) -> list[IntegerParam]:
    """Every integer path and query parameter of ``openapi``."""
    found = []
    for path, operations in openapi["paths"].items():
        for method, op in operations.items():
            schemes = [name for req in op.get("security", []) for name in req]
            for p in op.get("parameters", []):
                options = p["schema"].get("anyOf", [p["schema"]])
                schema = next(o for o in options if o.get("type") != "null")
                if p["in"] in ("path", "query") and schema.get("type") == "integer":
                    found.append(
                        IntegerParam(
                            method.upper(),
                            path,
                            p["in"],
                            p["name"],
                            schema["minimum"],
                            schemes[0] if schemes else None,
                        )
                    )
    return found


OPENAPI = api_openapi()
FIELDS = discover(OPENAPI)
INTEGERS = [f for f in FIELDS if f.kind == "integer"]
NUMBERS = [f for f in FIELDS if f.kind == "number"]
PARAMS = discover_params(OPENAPI)


def test_the_discovered_fields_are_those_the_app_serves(client) -> None:
    served = client.get("/openapi.json").json()
    assert sorted(map(str, discover(served))) == sorted(map(str, FIELDS))
    assert sorted(map(str, discover_params(served))) == sorted(map(str, PARAMS))
    assert {
        "POST /api/studies seed",
        "POST /api/runs seed",
        "POST /api/surveys stimuli.[].tree1.participant_id",
        "POST /api/surveys/me/screens/{position}/answers answers.*.confidence",
    } <= set(map(str, INTEGERS))
    assert {
        "POST /api/studies p",
        "POST /api/runs advice_scale",
        "PUT /api/studies/{study_id}/crowd gold_gate",
    } <= set(map(str, NUMBERS))
    assert {
        "GET /api/studies/{study_id} path:study_id",
        "GET /api/runs/{run_id}/metrics query:after",
        "GET /api/experiments/{experiment_id}/verdict query:step",
    } <= set(map(str, PARAMS))


def _schema_keys(node: Any, names: bool = False) -> Iterator[str]:
    """Every key of every schema object in ``node`` (a ``properties`` map's keys are field
    names, not keywords)."""
    if isinstance(node, dict):
        for key, value in node.items():
            if not names:
                yield key
            yield from _schema_keys(value, names=key == "properties" and not names)
    elif isinstance(node, list):
        for item in node:
            yield from _schema_keys(item)


def test_bounds_are_json_schema_keywords(client) -> None:
    served = client.get("/openapi.json").json()
    keys = list(_schema_keys(served))
    assert NOT_KEYWORDS.isdisjoint(keys), sorted(NOT_KEYWORDS & set(keys))
    assert keys.count("minimum") >= 80 and keys.count("maximum") >= 80
    scale = served["components"]["schemas"]["RunCreate"]["properties"]["advice_scale"]
    assert {"type": "number", "exclusiveMinimum": 0.0, "maximum": 100.0}.items() <= (
        scale["anyOf"][0].items()
    )


@pytest.fixture(scope="module")
def credentials(client: TestClient, study: dict[str, Any]) -> dict[str, dict[str, str]]:
    return scheme_headers(client, study["id"])


def _names(response: Any, where: str, name: str) -> list[dict[str, Any]]:
    """The 422's errors about ``name`` in ``where`` (``body``: an array item's loc ends in
    its index, so the field is the last name before it)."""
    assert response.status_code == 422, response.text
    return [
        e
        for e in response.json()["detail"]
        if e["loc"][0] == where
        and [n for n in e["loc"] if not isinstance(n, int)][-1] == name
        and e["type"] != "missing"
    ]


def _send(client: TestClient, field: NumberField, headers: dict[str, str], **body: Any) -> Any:
    url = re.sub(r"\{[^}]+\}", "1", field.path)
    return client.request(field.method, url, headers=headers, **body)


def _field_name(field: NumberField) -> str:
    return [n for n in field.names if n not in ("[]", "*")][-1]


@pytest.mark.parametrize("bad", BAD_INTEGERS, ids=repr)
@pytest.mark.parametrize("field", INTEGERS, ids=str)
def test_integer_fields_refuse_what_is_not_an_integer(
    client, credentials, field: NumberField, bad: Any
) -> None:
    response = _send(client, field, credentials[field.scheme], json=field.build(bad))
    assert _names(response, "body", _field_name(field)), response.text


@pytest.mark.parametrize("bad", [True, False], ids=repr)
@pytest.mark.parametrize("field", NUMBERS, ids=str)
def test_number_fields_refuse_booleans(client, credentials, field: NumberField, bad) -> None:
    response = _send(client, field, credentials[field.scheme], json=field.build(bad))
    assert _names(response, "body", _field_name(field)), response.text


@pytest.mark.parametrize("token", NON_FINITE)
@pytest.mark.parametrize("field", FIELDS, ids=str)
def test_number_fields_refuse_non_finite_values(
    client, credentials, field: NumberField, token: str
) -> None:
    text = json.dumps(field.build("@NUMBER@")).replace('"@NUMBER@"', token)  # as sent raw
    headers = credentials[field.scheme] | {"Content-Type": "application/json"}
    response = _send(client, field, headers, content=text)
    assert _names(response, "body", _field_name(field)), response.text


@pytest.mark.parametrize("param", PARAMS, ids=str)
def test_integer_parameters_take_plain_decimal_digits_only(
    client, credentials, param: IntegerParam
) -> None:
    headers = credentials[param.scheme] if param.scheme else {}
    for bad in BAD_PARAMS:
        url, query = param.request(bad)
        response = client.request(param.method, url, params=query, headers=headers, json={})
        assert _names(response, param.where, param.name), (bad, response.text)
    url, query = param.request(str(param.minimum))  # the smallest value, and "-1" where it is
    response = client.request(param.method, url, params=query, headers=headers, json={})
    refused = response.status_code == 422 and isinstance(response.json()["detail"], list)
    assert not (refused and _names(response, param.where, param.name)), response.text


def _int_rules(annotation: Any) -> tuple[bool, list[IntParam]]:
    """Whether ``annotation`` (a parameter's, ``Annotated`` and ``| None`` unwrapped) is an
    ``int``, and the :class:`IntParam` rules annotating it."""
    if get_origin(annotation) is Annotated:
        inner, *metadata = get_args(annotation)
        is_int, rules = _int_rules(inner)
        return is_int, rules + [m for m in metadata if isinstance(m, IntParam)]
    if get_origin(annotation) in (Union, types.UnionType):
        found = [_int_rules(a) for a in get_args(annotation)]
        return any(i for i, _ in found), [r for _, rules in found for r in rules]
    return annotation is int, []


def test_every_integer_parameter_of_every_route_is_an_int_param(client) -> None:
    """Pages too (they are not in the OpenAPI document): one type, one rule."""

    def dependants(d: Any) -> Iterator[Any]:
        yield d
        for sub in d.dependencies:
            yield from dependants(sub)

    checked, missing = 0, []
    for route in iter_route_contexts(client.app.routes):
        for d in dependants(route.dependant) if hasattr(route, "dependant") else ():
            for p in d.path_params + d.query_params:
                is_int, rules = _int_rules(p.field_info.annotation)
                rules += [m for m in p.field_info.metadata if isinstance(m, IntParam)]
                checked += is_int
                if is_int and not rules:
                    missing.append(f"{route.path} {p.name}")
    assert missing == [] and checked >= 90, (missing, checked)
