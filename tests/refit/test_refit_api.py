"""POST/GET /api/v1/refits: admins queue a refit and follow it; others are refused."""

from __future__ import annotations

import time

from sqlalchemy import select

from service.storage.models import FitRow
from tests.refit.fleet import seed_history


def test_admin_queues_a_refit_and_follows_it_to_the_end(env, breaker, tmp_path):
    ids = seed_history(env.Session, breaker, tmp_path / "captures", 6, per_kind=1)
    r = env.client.post("/api/v1/refits", json={"breaker": breaker.name}, headers=env.h("admin"))
    assert r.status_code == 202, r.text
    run = r.json()
    assert run["total"] == 6 and run["status"] in ("queued", "running", "done")
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        run = env.client.get(f"/api/v1/refits/{run['id']}", headers=env.h("admin")).json()
        if run["status"] == "done":
            break
        time.sleep(0.1)
    assert run["status"] == "done" and run["done"] == 6 and run["failed"] == 0
    with env.Session() as s:
        fits = list(s.scalars(select(FitRow).where(FitRow.operation_id.in_(ids))))
        assert {f.version for f in fits} == {2}
        newest_ao = {f.operation_id: f.parameters["AO"] for f in fits if f.kind == "open"}
    listed = env.client.get("/api/v1/refits", headers=env.h("admin")).json()
    assert [x["id"] for x in listed] == [run["id"]]
    # The web page's trend reads the newest version: the parameters endpoint returns one value each.
    trend = env.client.get("/api/v1/breakers/1/parameters", params={"name": "AO"}, headers=env.h("reader"))
    assert trend.status_code == 200
    assert {p["operation_id"]: p["value"] for p in trend.json()["points"]} == newest_ao


def test_only_admins_queue_or_read_refits(env):
    for role in ("reader", "operator"):
        assert env.client.post("/api/v1/refits", json={}, headers=env.h(role)).status_code == 403
        assert env.client.get("/api/v1/refits", headers=env.h(role)).status_code == 403
    assert env.client.post("/api/v1/refits", json={}).status_code == 401


def test_unknown_breaker_and_run_are_404(env):
    r = env.client.post("/api/v1/refits", json={"breaker": "nope"}, headers=env.h("admin"))
    assert r.status_code == 404 and "no breaker named 'nope'" in r.json()["detail"]
    assert env.client.get("/api/v1/refits/99", headers=env.h("admin")).status_code == 404
