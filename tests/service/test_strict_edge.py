"""Strict types at the API's edge and one breaker reference everywhere (issue 44 item 5): a boolean
or a string is not a number (schemathesis ST201 stored `"known_steps": false` as 0.0), and every
``/breakers/{…}`` route takes the breaker's id, its name or its tag."""

from __future__ import annotations

import pytest

from service.storage import crud
from tests.conftest import BREAKER_FILE


@pytest.fixture
def bid(env):
    with env.Session() as s, s.begin():
        return crud.register_breaker_file(s, path=BREAKER_FILE, tag="Q7").id


def _words(r) -> str:
    return str(r.json())


@pytest.mark.parametrize("body", [
    {"operation_id": 1, "known_steps": False},
    {"operation_id": 1, "known_steps": True},
    {"operation_id": 1, "known_steps": "3"},
    {"operation_id": True, "known_steps": 1.0},
    {"operation_id": "1", "known_steps": 1.0},
])
def test_commissioning_refuses_a_boolean_or_a_string_for_a_number(env, bid, body):
    r = env.client.post(f"/api/v1/breakers/{bid}/commissioning", json=body, headers=env.h("operator"))
    assert r.status_code == 422, r.text
    assert "a number is expected" in _words(r)
    with env.Session() as s:
        assert crud.get_breaker(s, breaker_id=bid) is not None  # nothing else changed: no record made
    assert env.client.get(f"/api/v1/breakers/{bid}/commissioning", headers=env.h("reader")).status_code == 404


@pytest.mark.parametrize("last", [True, "10", 10.5])  # (10.0 is an integer to JSON Schema: taken)
def test_a_breaker_diagnosis_refuses_a_boolean_or_a_string_for_a_count(env, bid, last):
    r = env.client.post(f"/api/v1/breakers/{bid}/diagnoses", json={"operation": "open", "last": last},
                        headers=env.h("operator"))
    assert r.status_code == 422, r.text
    assert "last" in _words(r)


@pytest.mark.parametrize("path", ["", "/operations", "/health", "/parameters?name=DO", "/alarms/history",
                                  "/compensation"])
def test_every_breaker_route_takes_the_id_the_name_and_the_tag(env, bid, path):
    with env.Session() as s:
        name = crud.get_breaker(s, breaker_id=bid).name
    answers = []
    for ref in (str(bid), name, "Q7"):
        r = env.client.get(f"/api/v1/breakers/{ref}{path}", headers=env.h("reader"))
        assert r.status_code == 200, (ref, r.text)
        answers.append(r.json())
    assert answers[0] == answers[1] == answers[2]


def test_an_integral_float_is_an_integer_as_json_schema_says(env, bid):
    r = env.client.post(f"/api/v1/breakers/{bid}/commissioning", json={"operation_id": 1.0, "known_steps": 1},
                        headers=env.h("operator"))
    assert r.status_code == 404 and "operation" in r.json()["detail"]  # read as operation 1, which is not there


def test_an_unknown_breaker_reference_is_a_404_in_words(env, bid):
    for ref in ("nosuch", "99999", "3000000000", "\u00b9", "\u0661"):  # superscript one, Arabic-Indic one
        r = env.client.get(f"/api/v1/breakers/{ref}/operations", headers=env.h("reader"))
        assert r.status_code == 404
        assert ref in r.json()["detail"] and "id, name or tag" in r.json()["detail"]


@pytest.mark.parametrize("since", ["1700000000", "0", "1e9"])
def test_a_number_is_not_a_date(env, bid, since):
    r = env.client.get(f"/api/v1/breakers/{bid}/parameters", params={"name": "DO", "since": since},
                       headers=env.h("reader"))
    assert r.status_code == 422
    assert "ISO 8601" in _words(r)
    ok = env.client.get(f"/api/v1/breakers/{bid}/parameters", params={"name": "DO", "since": "2026-01-01T00:00:00Z"},
                        headers=env.h("reader"))
    assert ok.status_code == 200
