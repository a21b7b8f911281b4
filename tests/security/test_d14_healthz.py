"""D14: /healthz without a key says only ok or degraded; the details need a key."""

from __future__ import annotations

import time


def test_healthz_without_a_key_says_only_the_status(env):
    r = env.client.get("/healthz")
    assert r.status_code == 200 and r.json() == {"status": "ok"}
    detailed = env.client.get("/healthz", headers=env.h("reader")).json()
    assert detailed["status"] == "ok" and detailed["database"] == "ok" and "daq" in detailed
    assert env.client.get("/healthz", headers={"X-API-Key": "hvcb_wrong"}).status_code == 401


def test_degraded_is_all_an_anonymous_caller_learns(env, monkeypatch):
    from sqlalchemy.exc import OperationalError

    def broken():
        raise OperationalError("select 1", {}, Exception("database is down"))

    monkeypatch.setattr(env.app.state, "PrioritySession", broken)
    deadline = time.monotonic() + 30  # the snapshot thread notices within a refresh
    while time.monotonic() < deadline:
        r = env.client.get("/healthz")
        if r.json() != {"status": "ok"}:
            break
        time.sleep(0.1)
    assert r.status_code == 200 and r.json() == {"status": "degraded"}
