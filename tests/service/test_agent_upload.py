"""The server side of the edge agent: the `agent` role may upload and nothing else, and an upload
with an Idempotency-Key (the capture's content hash) is stored once however often it is sent."""

from __future__ import annotations

import re

from sqlalchemy import func, select

from comtrade_bytes import comtrade_pair
from conftest import synth
from service.jobs.upload import content_hash
from service.storage import crud
from service.storage.models import OperationRow

UPLOAD = ("POST", "/api/v1/breakers/{breaker_id}/captures")


def _agent_key(env) -> str:
    with env.Session() as s, s.begin():
        return crud.create_api_key(s, name="edge-1", role="agent")[1]


def test_agent_key_uploads_and_nothing_else(env, breaker):
    h = {"X-API-Key": _agent_key(env)}
    for path, ops in env.app.openapi()["paths"].items():
        if not (path.startswith("/api/v1") or path == "/metrics"):
            continue
        for method in ops:
            if (method.upper(), path) == UPLOAD:
                continue
            r = env.client.request(method.upper(), re.sub(r"\{[^}]+\}", "1", path), headers=h)
            assert r.status_code == 403, (method, path, r.status_code)
    cfg, dat = comtrade_pair(synth(breaker, "open", 3))
    r = env.client.post("/api/v1/breakers/1/captures", headers=h, files=[("files", ("a.cfg", cfg)),
                                                                         ("files", ("a.dat", dat))])
    assert r.status_code == 202, r.text
    op = env.client.get(f"/api/v1/operations/{r.json()['operation_id']}", headers=env.h("reader")).json()
    assert op["source"] == "agent"


def test_a_retried_capture_is_stored_once(env, breaker):
    h = {"X-API-Key": _agent_key(env)}
    cfg, dat = comtrade_pair(synth(breaker, "open", 4))
    key = content_hash(cfg, dat)
    files = [("files", ("a.cfg", cfg)), ("files", ("a.dat", dat))]
    first = env.client.post("/api/v1/breakers/1/captures", headers={**h, "Idempotency-Key": key}, files=files)
    again = env.client.post("/api/v1/breakers/1/captures", headers={**h, "Idempotency-Key": key}, files=files)
    assert first.status_code == 202 and first.json()["status"] == "queued"
    assert again.status_code == 200 and again.json()["status"] == "duplicate"
    assert again.json()["operation_id"] == first.json()["operation_id"] and again.json()["capture_key"] == key
    with env.Session() as s:
        assert s.scalar(select(func.count()).select_from(OperationRow)) == 1
        assert s.scalar(select(OperationRow.capture_key)) == key


def test_idempotency_key_must_be_the_content_hash(env, breaker):
    h = {"X-API-Key": _agent_key(env)}
    cfg, dat = comtrade_pair(synth(breaker, "open", 5))
    files = [("files", ("a.cfg", cfg)), ("files", ("a.dat", dat))]
    wrong = content_hash(cfg, dat + b"1,0,0,0\n")
    r = env.client.post("/api/v1/breakers/1/captures", headers={**h, "Idempotency-Key": wrong}, files=files)
    assert r.status_code == 422 and "content hash" in r.json()["detail"]
    r = env.client.post("/api/v1/breakers/1/captures", headers={**h, "Idempotency-Key": "not-a-hash"}, files=files)
    assert r.status_code == 422
    with env.Session() as s:
        assert s.scalar(select(func.count()).select_from(OperationRow)) == 0


def test_every_key_the_documented_schema_admits_passes_the_header_check(env, breaker):
    """The contract as documented: a key the OpenAPI header schema admits is never refused by the
    header's own check ("String should match pattern"); only the content hash can refuse it."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    h = {"X-API-Key": _agent_key(env)}
    op = env.app.openapi()["paths"][UPLOAD[1]]["post"]
    schema = next(p["schema"] for p in op["parameters"] if p["name"] == "Idempotency-Key")
    assert schema["type"] == "string" and "anyOf" not in schema  # a header is left out, never null
    cfg, dat = comtrade_pair(synth(breaker, "open", 6))
    files = [("files", ("a.cfg", cfg)), ("files", ("a.dat", dat))]
    right = content_hash(cfg, dat)

    @settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(st.from_regex(schema["pattern"], fullmatch=True).filter(lambda k: k != right))
    def check(key):
        r = env.client.post(UPLOAD[1].format(breaker_id=1), headers={**h, "Idempotency-Key": key}, files=files)
        assert r.status_code == 422 and "content hash" in r.json()["detail"], r.text

    check()
