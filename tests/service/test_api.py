"""The REST API through HTTP on a real database (SQLite, and PostgreSQL when configured)."""

from __future__ import annotations

import re
from datetime import datetime, timedelta, timezone

import pytest
from sqlalchemy import func, select

from service.storage import crud
from service.storage.models import AlarmRow, FitRow, OperationRow

from comtrade_bytes import comtrade_pair, zipped
from conftest import synth

Z_TIME = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?Z$")


def _counts(env):
    with env.Session() as s:
        return (s.scalar(select(func.count()).select_from(OperationRow)),
                s.scalar(select(func.count()).select_from(FitRow)), len(env.app.state.monitor.spool))


def _ingest(env, breaker, kind="open", seed=0, **kw):
    res = env.app.state.monitor.ingest(synth(breaker, kind, seed, **kw), breaker_id=1, operation=kind)
    assert res.operation_id is not None
    return res.operation_id


# -- auth ----------------------------------------------------------------------------------------
OPERATOR_ROUTES = {("POST", "/api/v1/breakers/{breaker_id}/captures"), ("POST", "/api/v1/alarms/{alarm_id}/ack")}
# the alarm lifecycle and SCADA temperature (service/api/routes_alarms.py)
OPERATOR_ROUTES |= {("POST", "/api/v1/alarms/{alarm_id}/shelve"), ("POST", "/api/v1/alarms/{alarm_id}/unshelve"),
                    ("POST", "/api/v1/breakers/{breaker_id}/out-of-service"),
                    ("PUT", "/api/v1/breakers/{breaker}/temperature")}
# the unit's commissioning pair (service/api/routes_setting.py)
OPERATOR_ROUTES |= {("POST", "/api/v1/breakers/{name}/commissioning")}
# the engineer's maintenance log (service/api/routes_maintenance.py, issue 50)
OPERATOR_ROUTES |= {("POST", "/api/v1/breakers/{name}/maintenance")}
ADMIN_ROUTES = {("POST", "/api/v1/breakers/{breaker_id}/return-to-service"),
                ("POST", "/api/v1/breakers"), ("POST", "/api/v1/breakers/{breaker_id}/baseline/reset"),
                ("GET", "/api/v1/keys"), ("POST", "/api/v1/keys"), ("DELETE", "/api/v1/keys/{key_id}"),
                ("POST", "/api/v1/refits"), ("GET", "/api/v1/refits"), ("GET", "/api/v1/refits/{run_id}")}


def _routes(app):
    for path, ops in app.openapi()["paths"].items():
        if path.startswith("/api/v1") or path == "/metrics":
            for method in ops:
                yield method.upper(), path


def test_every_endpoint_needs_a_key_and_the_right_role(env):
    routes = list(_routes(env.app))
    assert len(routes) >= 16
    for method, path in routes:
        url = re.sub(r"\{[^}]+\}", "1", path)
        assert env.client.request(method, url).status_code == 401, (method, path)
        assert env.client.request(method, url, headers={"X-API-Key": "hvcb_wrong"}).status_code == 401
        need = "admin" if (method, path) in ADMIN_ROUTES else "operator" if (method, path) in OPERATOR_ROUTES \
            else "reader"
        for role in ("reader", "operator")[: {"reader": 0, "operator": 1, "admin": 2}[need]]:
            r = env.client.request(method, url, headers=env.h(role))
            assert r.status_code == 403, (method, path, role, r.text)
        r = env.client.request(method, url, headers=env.h(need))
        assert r.status_code not in (401, 403), (method, path, r.text)


def test_healthz_is_open_and_reports_database(env):
    r = env.client.get("/healthz")
    assert r.status_code == 200 and r.json() == {"status": "ok"}  # details need a key (D14)
    r = env.client.get("/healthz", headers=env.h("reader"))
    assert r.status_code == 200 and r.json()["database"] == "ok"


def test_generated_admin_key_is_stored_hashed_with_0600_file(env):
    key_file = env.settings.key_file
    assert oct(key_file.stat().st_mode & 0o777) == "0o600"
    key = key_file.read_text().strip()
    assert key == env.keys["admin"]
    from service.storage.models import ApiKeyRow

    with env.Session() as s:
        stored = [row.key_hash for row in s.scalars(select(ApiKeyRow))]
    assert key not in stored and crud.hash_key(key) in stored


def test_key_lifecycle(env):
    r = env.client.post("/api/v1/keys", json={"name": "scada", "role": "reader"}, headers=env.h())
    assert r.status_code == 201
    new = r.json()
    assert env.client.get("/api/v1/scada/points", headers={"X-API-Key": new["key"]}).status_code == 200
    assert env.client.delete(f"/api/v1/keys/{new['id']}", headers=env.h()).status_code == 200
    assert env.client.get("/api/v1/scada/points", headers={"X-API-Key": new["key"]}).status_code == 401


# -- reading -------------------------------------------------------------------------------------
def test_breakers_listed_with_design_parameters(env):
    r = env.client.get("/api/v1/breakers", headers=env.h("reader"))
    assert r.status_code == 200
    (b,) = r.json()
    assert b["name"] == "reference-252kV" and b["tag"] == "Q1" and Z_TIME.match(b["created_at"])
    d = env.client.get(f"/api/v1/breakers/{b['id']}", headers=env.h("reader")).json()
    assert d["design_parameters"]["DO"] == pytest.approx(39.51, rel=1e-3)
    assert env.client.get("/api/v1/breakers/999", headers=env.h("reader")).status_code == 404


def test_fits_visible_through_operations_health_trend_curve_and_scada(env, breaker):
    t0 = datetime.now(timezone.utc) - timedelta(minutes=5)
    op_open = _ingest(env, breaker, "open", 1, start_time=t0)
    op_close = _ingest(env, breaker, "close", 2, start_time=t0 + timedelta(seconds=1))
    env.wait_fits(2)
    h = env.h("reader")
    ops = env.client.get("/api/v1/breakers/1/operations?limit=10", headers=h).json()
    assert [o["id"] for o in ops] == [op_close, op_open]
    o = env.client.get(f"/api/v1/operations/{op_open}", headers=h).json()
    assert o["fit"]["status"] == "done", o["fit"]
    assert o["fit"]["parameters"]["DO"] == pytest.approx(breaker.design_parameters()["DO"], rel=0.05)
    assert Z_TIME.match(o["occurred_at"]) and Z_TIME.match(o["fit"]["finished_at"])
    c = env.client.get(f"/api/v1/operations/{op_close}", headers=h).json()["fit"]
    assert c["status"] == "done" and c["dc_source"] == f"opening fit of operation {op_open}"
    assert c["dc_used"] == pytest.approx(o["fit"]["parameters"]["AO"])

    curve = env.client.get(f"/api/v1/operations/{op_open}/curve?points=300", headers=h).json()
    assert len(curve["t_s"]) == len(curve["measured_rad"]) == len(curve["fitted_rad"]) <= 300
    res = [v for v in curve["residual_rad"] if v is not None]
    assert len(res) > 100 and max(abs(v) for v in res) < 0.05

    health = env.client.get("/api/v1/breakers/1/health", headers=h).json()
    assert health["opening"]["parameters"]["DO"]["unit"] == "s^-1"
    assert len(health["opening"]["parameters"]["DO"]["ci95"]) == 2
    assert health["closing"]["operation_id"] == op_close
    assert health["status"] == "unknown"  # no baseline yet
    assert "opening" in health["characteristics"]

    trend = env.client.get("/api/v1/breakers/1/parameters", params={"name": "DO", "since": t0.isoformat()},
                           headers=h).json()
    assert [p["operation_id"] for p in trend["points"]] == [op_open]
    later = (t0 + timedelta(hours=1)).isoformat()
    assert env.client.get("/api/v1/breakers/1/parameters", params={"name": "DO", "since": later},
                          headers=h).json()["points"] == []
    assert env.client.get("/api/v1/breakers/1/parameters?name=XX", headers=h).status_code == 422

    points = {p["point"]: p for p in env.client.get("/api/v1/scada/points", headers=h).json()}
    assert points["Q1.opening.DO"]["quality"] == "good"
    assert points["Q1.opening.DO"]["value"] == pytest.approx(o["fit"]["parameters"]["DO"])
    assert Z_TIME.match(points["Q1.opening.DO"]["timestamp"])
    # closing fits of this design are ill-conditioned or not: quality follows `identifiable`
    assert points["Q1.closing.AC"]["quality"] == ("good" if c["identifiable"] else "uncertain")

    metrics = env.client.get("/metrics", headers=h).text
    assert 'hvcb_fits{status="done"} 2.0' in metrics and "hvcb_queue_depth 0.0" in metrics
    assert "hvcb_fit_duration_seconds_count 2.0" in metrics and "hvcb_crc_errors" in metrics


def test_closing_without_opening_uses_breaker_file_dc(env, breaker):
    op = _ingest(env, breaker, "close", 3)
    env.wait_fits(1)
    fit = env.client.get(f"/api/v1/operations/{op}", headers=env.h("reader")).json()["fit"]
    assert fit["status"] == "done"
    assert fit["dc_source"] == "breaker file design value"
    assert fit["dc_used"] == pytest.approx(breaker.design_parameters()["DC"])


def test_scada_quality_bad_when_stale_or_daq_down(env, breaker):
    old = datetime.now(timezone.utc) - timedelta(days=30)
    _ingest(env, breaker, "open", 4, start_time=old)
    env.wait_fits(1)
    points = {p["point"]: p for p in env.client.get("/api/v1/scada/points", headers=env.h("reader")).json()}
    assert points["Q1.opening.DO"]["quality"] == "bad"  # stale
    assert points["Q1.closing.AC"]["value"] is None and points["Q1.closing.AC"]["quality"] == "bad"
    _ingest(env, breaker, "open", 5)
    env.wait_fits(2)
    env.app.state.scada_cache = None
    points = {p["point"]: p for p in env.client.get("/api/v1/scada/points", headers=env.h("reader")).json()}
    assert points["Q1.opening.DO"]["quality"] == "good"
    with env.Session() as s, s.begin():
        crud.report_daq(s, breaker_id=1, connected=False)
    env.app.state.scada_cache = None
    points = {p["point"]: p for p in env.client.get("/api/v1/scada/points", headers=env.h("reader")).json()}
    assert points["Q1.opening.DO"]["quality"] == "bad" and points["Q1.daq.connected"]["value"] == 0.0


# -- uploads -------------------------------------------------------------------------------------
def test_upload_pair_and_zip_are_accepted_and_fitted(env, breaker):
    cfg, dat = comtrade_pair(synth(breaker, "open", 6))
    r = env.client.post("/api/v1/breakers/1/captures", headers=env.h("operator"),
                        files=[("files", ("a.cfg", cfg)), ("files", ("a.dat", dat))])
    assert r.status_code == 202, r.text
    assert r.json()["operation"] == "open" and r.json()["status"] == "queued"
    r2 = env.client.post("/api/v1/breakers/1/captures", headers=env.h("operator"),
                         files=[("files", ("b.zip", zipped(cfg, dat)))], data={"operation": "open"})
    assert r2.status_code == 202, r2.text
    env.wait_fits(2)
    for op in (r.json()["operation_id"], r2.json()["operation_id"]):
        fit = env.client.get(f"/api/v1/operations/{op}", headers=env.h("reader")).json()["fit"]
        assert fit["status"] == "done" and fit["parameters"]["DO"] > 30


@pytest.mark.parametrize("case", ["garbage_pair", "only_cfg", "bad_zip", "wrong_unit", "no_travel",
                                  "three_files", "not_moving", "too_big", "bad_operation", "no_breaker"])
def test_malformed_uploads_are_4xx_and_leave_db_unchanged(env, breaker, case):
    cap = synth(breaker, "open", 7)
    cfg, dat = comtrade_pair(cap)
    url = "/api/v1/breakers/1/captures"
    data = None
    files = {
        "garbage_pair": [("files", ("x.cfg", b"\x00\xffnot comtrade")), ("files", ("x.dat", b"1,2,3"))],
        "only_cfg": [("files", ("x.cfg", cfg))],
        "bad_zip": [("files", ("x.zip", b"PK\x03\x04broken"))],
        "wrong_unit": [("files", ("x.cfg", cfg.replace(b",rad,", b",furlong,"))), ("files", ("x.dat", dat))],
        "no_travel": [("files", ("x.cfg", cfg.replace(b"travel", b"stroke"))), ("files", ("x.dat", dat))],
        "three_files": [("files", ("x.cfg", cfg)), ("files", ("x.dat", dat)), ("files", ("y.dat", dat))],
        "not_moving": list(zip(["files", "files"], [("x.cfg", comtrade_pair(
            type(cap)(**{**cap.__dict__, "travel": cap.travel * 0 + 0.5}))[0]),
            ("x.dat", comtrade_pair(type(cap)(**{**cap.__dict__, "travel": cap.travel * 0 + 0.5}))[1])])),
        "too_big": [("files", ("x.cfg", cfg)), ("files", ("x.dat", dat * 200))],
        "bad_operation": [("files", ("x.cfg", cfg)), ("files", ("x.dat", dat))],
        "no_breaker": [("files", ("x.cfg", cfg)), ("files", ("x.dat", dat))],
    }[case]
    if case == "bad_operation":
        data = {"operation": "sideways"}
    if case == "no_breaker":
        url = "/api/v1/breakers/42/captures"
    before = _counts(env)
    r = env.client.post(url, headers=env.h("operator"), files=files, data=data)
    assert 400 <= r.status_code < 500, (case, r.status_code, r.text)
    assert r.json()["detail"], case
    assert _counts(env) == before


# -- alarms --------------------------------------------------------------------------------------
def test_do_leak_raises_alarm_that_can_be_acknowledged_and_reset(env, breaker):
    from tests.fit_rows import store_leak

    # Parameter history straight into the fit table (the drift detector is tested on its own);
    # ten healthy fits form the baseline in this test's settings, then DO falls 2 %/operation.
    settings = env.settings.drift_settings.__class__.from_mapping({**env.settings.alarms, "baseline_n": 10})
    events = store_leak(env.Session, settings, t0=datetime.now(timezone.utc) - timedelta(hours=1),
                        step=timedelta(seconds=1), n=30, start=14, key="k")
    raised_at = next((i for i, ev in enumerate(events) if any(e.kind == "raised" for e in ev)), None)
    assert raised_at is not None and 15 <= raised_at <= 25
    alarms = env.client.get("/api/v1/alarms?state=active", headers=env.h("reader")).json()
    assert [a["parameter"] for a in alarms] == ["DO"]
    a = alarms[0]
    assert a["evidence"]["baseline"]["n"] >= 9 and a["evidence"]["current"]["ci95"]
    assert "oil leak" in a["message"]
    health = env.client.get("/api/v1/breakers/1/health", headers=env.h("reader")).json()
    assert health["active_alarms"][0]["id"] == a["id"]
    r = env.client.post(f"/api/v1/alarms/{a['id']}/ack", json={"comment": "crew sent"}, headers=env.h("operator"))
    assert r.status_code == 200 and r.json()["state"] == "acknowledged" and r.json()["acknowledged_by"] == "test-operator"
    assert env.client.post("/api/v1/alarms/999/ack", headers=env.h("operator")).status_code == 404
    r = env.client.post("/api/v1/breakers/1/baseline/reset", json={"reason": "buffer refilled"}, headers=env.h())
    assert r.status_code == 200
    assert env.client.get("/api/v1/alarms?state=active", headers=env.h("reader")).json() == []
    cleared = env.client.get("/api/v1/alarms?state=cleared", headers=env.h("reader")).json()
    assert cleared[0]["id"] == a["id"] and Z_TIME.match(cleared[0]["cleared_at"])
    assert env.client.post(f"/api/v1/alarms/{a['id']}/ack", headers=env.h("operator")).status_code == 409
    with env.Session() as s:
        assert s.scalar(select(func.count()).select_from(AlarmRow)) == 1


def test_admin_registers_breaker_and_bad_file_is_422(env):
    from conftest import BREAKER_FILE

    text = BREAKER_FILE.read_text().replace('name = "reference-252kV"', 'name = "bay-2"')
    cam = (BREAKER_FILE.parent / "reference-252kV.cam.csv").read_text()
    r = env.client.post("/api/v1/breakers", json={"breaker_file": text, "cam_table": cam, "tag": "Q2"},
                        headers=env.h())
    assert r.status_code == 201 and r.json()["tag"] == "Q2"
    assert env.client.post("/api/v1/breakers", json={"breaker_file": text, "cam_table": cam},
                           headers=env.h()).status_code == 409
    bad = env.client.post("/api/v1/breakers", json={"breaker_file": "name = 'x'", "cam_table": cam}, headers=env.h())
    assert bad.status_code == 422
    assert len(env.client.get("/api/v1/breakers", headers=env.h("reader")).json()) == 2
