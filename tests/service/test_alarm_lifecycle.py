"""Alarm lifecycle over the REST API (shelve, out of service, history with first-out, evidence,
audit) and temperature from its three sources: SCADA, the upload field and a capture channel."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
from sqlalchemy import select

from comtrade_bytes import comtrade_pair
from conftest import BREAKER_FILE, synth
from service.storage import crud
from service.storage.models import AlarmActionRow, OperationRow
from tests.web_forms import CSRF, sign_in


def _op(s, i: int, t: datetime, *, temperature=None, breaker_id=1):
    op, _ = crud.create_operation(s, capture_key=f"k{i}-{breaker_id}", breaker_id=breaker_id, kind="open",
                                  occurred_at=t, source="replay", capture_path="/nonexistent.csv",
                                  capture_sha256="0" * 64, flags=[], sample_rate=1.0, n_samples=1,
                                  temperature_c=temperature, temperature_source="agent" if temperature else None)
    return op


def _leak(env, *, n=40, start=25, temperature=None):
    """Fits straight into the fit table: the first 20 healthy fits form the baseline, then DO
    falls 2 %/operation from ``start``. Returns the settings used (the service's)."""
    from service.jobs.fit import update_drift

    rng = np.random.default_rng(3)
    t0 = datetime.now(timezone.utc) - timedelta(hours=2)
    settings = env.settings.drift_settings
    for i in range(n):
        do = 39.5 * (1 + rng.normal(0, 0.003)) * (0.98 ** max(0, i - start))
        with env.Session() as s, s.begin():
            op = _op(s, i, t0 + timedelta(seconds=i), temperature=temperature)
            crud.claim_fit(s, operation_id=op.id, worker="test")
            crud.store_fit_result(s, operation_id=op.id, curve=None, result={
                "parameters": {"AO": 3424.0, "BO": 4806.0 * (1 + rng.normal(0, 0.002)), "DO": do, "EO": 3950.0},
                "ci95": {"DO": [do - 0.3, do + 0.3], "BO": [4790.0, 4822.0]}, "identifiable": True})
            update_drift(s, breaker_id=1, settings=settings)
    return settings


def _active(env):
    return env.client.get("/api/v1/alarms?state=active", headers=env.h("reader")).json()


def test_shelve_unshelve_audit_and_history_with_first_out(env):
    _leak(env)
    (a,) = _active(env)
    url = f"/api/v1/alarms/{a['id']}"
    # a reason and a time limit are required, in words
    r = env.client.post(f"{url}/shelve", json={"minutes": 60, "reason": ""}, headers=env.h("operator"))
    assert r.status_code == 422
    r = env.client.post(f"{url}/shelve", json={"minutes": 8 * 24 * 60, "reason": "outage"}, headers=env.h("operator"))
    assert r.status_code == 422
    assert env.client.post(f"{url}/shelve", json={"minutes": 60, "reason": "crew on site"},
                           headers=env.h("reader")).status_code == 403
    r = env.client.post(f"{url}/shelve", json={"minutes": 90, "reason": "crew on site"}, headers=env.h("operator"))
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["shelved_by"] == "test-operator" and body["shelve_reason"] == "crew on site"
    until = datetime.fromisoformat(body["shelved_until"].replace("Z", "+00:00"))
    assert timedelta(minutes=89) < until - datetime.now(timezone.utc) <= timedelta(minutes=90)

    hist = env.client.get("/api/v1/breakers/1/alarms/history", headers=env.h("reader")).json()
    assert [h["order"] for h in hist] == [1] and hist[0]["first_out"] and hist[0]["shelved"]
    assert [x["action"] for x in hist[0]["actions"]] == ["shelve"]

    r = env.client.post(f"{url}/ack", json={"comment": "seen"}, headers=env.h("operator"))
    assert r.status_code == 200
    r = env.client.post(f"{url}/unshelve", json={"reason": "crew left"}, headers=env.h("operator"))
    assert r.status_code == 200 and r.json()["shelved_until"] is not None
    r = env.client.post(f"{url}/unshelve", headers=env.h("operator"))
    assert r.status_code == 409 and "not shelved" in r.json()["detail"]
    audit = env.client.get(f"{url}/actions", headers=env.h("reader")).json()
    assert [(x["action"], x["by"]) for x in audit] == [("unshelve", "test-operator"),
                                                       ("acknowledge", "test-operator"),
                                                       ("shelve", "test-operator")]
    assert audit[2]["reason"] == "crew on site" and audit[2]["until"]


def test_out_of_service_stops_watching_and_return_resets_the_baseline(env):
    from service.jobs.fit import update_drift

    settings = _leak(env, n=24)
    assert _active(env) == []
    r = env.client.post("/api/v1/breakers/1/out-of-service", json={"reason": "WO-1234 buffer refill"},
                        headers=env.h("operator"))
    assert r.status_code == 200 and r.json()["in_service"] is False
    again = env.client.post("/api/v1/breakers/1/out-of-service", json={"reason": "again"}, headers=env.h("operator"))
    assert again.status_code == 409 and "already out of service" in again.json()["detail"]
    # during maintenance DO is all over the place: nothing is watched
    t0 = datetime.now(timezone.utc) - timedelta(minutes=30)
    for i in range(100, 112):
        with env.Session() as s, s.begin():
            op = _op(s, i, t0 + timedelta(seconds=i))
            crud.claim_fit(s, operation_id=op.id, worker="test")
            crud.store_fit_result(s, operation_id=op.id, curve=None, result={
                "parameters": {"AO": 3424.0, "BO": 4806.0, "DO": 20.0 + i % 3, "EO": 3950.0},
                "ci95": {"DO": [19.0, 23.0]}, "identifiable": True})
            assert update_drift(s, breaker_id=1, settings=settings) == []
    assert _active(env) == []
    assert env.client.post("/api/v1/breakers/1/return-to-service", headers=env.h("operator")).status_code == 403
    r = env.client.post("/api/v1/breakers/1/return-to-service", json={"reason": "refilled"}, headers=env.h())
    assert r.status_code == 200 and r.json()["in_service"] is True
    comp = env.client.get("/api/v1/breakers/1/compensation", headers=env.h("reader")).json()["parameters"]
    assert comp["DO"]["phase"] == "baseline" and comp["DO"]["baseline_fits"] == 0  # fresh baseline
    with env.Session() as s:
        actions = [a.action for a in s.scalars(select(AlarmActionRow).order_by(AlarmActionRow.id))]
    assert actions == ["out_of_service", "return_to_service"]
    assert env.client.post("/api/v1/breakers/1/return-to-service", headers=env.h()).status_code == 409


def test_evidence_series_has_band_cusum_thresholds_and_says_not_compensated(env):
    _leak(env)
    r = env.client.get("/api/v1/breakers/1/alarms/evidence/DO", headers=env.h("reader"))
    assert r.status_code == 200, r.text
    ev = r.json()
    ser = ev["series"]
    n0 = env.settings.drift_settings.baseline_n
    assert len(ser["value"]) == 40 and ser["expected"][:n0] == [None] * n0
    assert ev["status"] == "not temperature-compensated" and ev["compensated"] is False
    i = max(range(40), key=lambda j: ser["statistic"][j] or 0)
    assert ser["statistic"][i] >= ev["thresholds"]["alarm"] and ser["value"][i] < ser["band_low"][i]
    assert all(lo < e < hi for lo, e, hi in zip(ser["band_low"][n0:], ser["expected"][n0:], ser["band_high"][n0:]))
    health = env.client.get("/api/v1/breakers/1/health", headers=env.h("reader")).json()
    assert health["temperature_compensation"] == {"DO": "not temperature-compensated",
                                                  "BO": "not temperature-compensated",
                                                  "latch_time_s": "not temperature-compensated"}  # watched by default
    assert env.client.get("/api/v1/breakers/1/alarms/evidence/AO", headers=env.h("reader")).status_code == 404


def test_temperature_on_every_operation_makes_the_breaker_compensated(env):
    _leak(env, n=24, temperature=15.0)
    health = env.client.get("/api/v1/breakers/1/health", headers=env.h("reader")).json()
    assert health["temperature_compensation"]["DO"] == "temperature-compensated"
    ev = env.client.get("/api/v1/breakers/1/alarms/evidence/DO", headers=env.h("reader")).json()
    assert ev["series"]["temperature_c"] == [15.0] * 24


def test_scada_temperature_applies_to_operations_without_their_own(env):
    r = env.client.put("/api/v1/breakers/reference-252kV/temperature", json={"temperature_c": -12.5},
                       headers=env.h("operator"))
    assert r.status_code == 200, r.text
    assert r.json()["temperature_c"] == -12.5 and r.json()["applies_for_s"] == 3600
    assert env.client.put("/api/v1/breakers/reference-252kV/temperature", json={"temperature_c": 500},
                          headers=env.h("operator")).status_code == 422
    assert env.client.put("/api/v1/breakers/nope/temperature", json={"temperature_c": 5},
                          headers=env.h("operator")).status_code == 404
    assert env.client.put("/api/v1/breakers/1/temperature", json={"temperature_c": 5},
                          headers=env.h("reader")).status_code == 403
    now = datetime.now(timezone.utc)
    with env.Session() as s, s.begin():
        own = _op(s, 1, now, temperature=30.0)
        scada = _op(s, 2, now)
        late = _op(s, 3, now + timedelta(hours=2))  # the SCADA value is too old by then
        got = [(o.temperature_c, o.temperature_source) for o in (own, scada, late)]
    assert got == [(30.0, "agent"), (-12.5, "scada"), (None, None)]


def _three_channel_pair(capture, temp_c: float) -> tuple[bytes, bytes]:
    cfg, dat = comtrade_pair(capture)
    lines = cfg.decode().split("\n")
    lines[1] = "3,3A,0D"
    lines.insert(4, "3,mech_temp,,,degC,0.01,0,0,-99999,99999,1,1,P")
    rows = [f"{r},{int(round(temp_c / 0.01))}" for r in dat.decode().strip().split("\n")]
    return "\n".join(lines).encode(), ("\n".join(rows) + "\n").encode()


def test_temperature_from_the_upload_field_and_from_a_capture_channel(env, breaker):
    cap = synth(breaker, "open", 6)
    cfg, dat = comtrade_pair(cap)
    files = [("files", ("a.cfg", cfg)), ("files", ("a.dat", dat))]
    bad = env.client.post("/api/v1/breakers/1/captures", headers=env.h("operator"), files=files,
                          data={"temperature_c": "hot"})
    assert bad.status_code == 422
    r = env.client.post("/api/v1/breakers/1/captures", headers=env.h("operator"), files=files,
                        data={"temperature_c": "21.5"})
    assert r.status_code == 202, r.text
    op = env.client.get(f"/api/v1/operations/{r.json()['operation_id']}", headers=env.h("reader")).json()
    assert op["temperature_c"] == 21.5 and op["temperature_source"] == "upload"

    # a breaker whose file names a temperature channel
    text = BREAKER_FILE.read_text().replace('name = "reference-252kV"', 'name = "bay-t"').replace(
        'vibration = "vibration"', 'vibration = "vibration"\ntemperature = "mech_temp"')
    cam = (BREAKER_FILE.parent / "reference-252kV.cam.csv").read_text()
    b = env.client.post("/api/v1/breakers", json={"breaker_file": text, "cam_table": cam, "tag": "QT"},
                        headers=env.h()).json()
    cfg3, dat3 = _three_channel_pair(cap, -7.25)
    r = env.client.post(f"/api/v1/breakers/{b['id']}/captures", headers=env.h("operator"),
                        files=[("files", ("c.cfg", cfg3)), ("files", ("c.dat", dat3))])
    assert r.status_code == 202, r.text
    with env.Session() as s:
        row = s.get(OperationRow, r.json()["operation_id"])
        assert (row.temperature_c, row.temperature_source) == (-7.25, "channel")
    env.wait_fits()


def _web_sign_in(env, role="operator"):
    sign_in(env.client, env.keys[role])


def _csrf(html: str) -> str:
    return CSRF.search(html).group(1)


def test_web_alarm_page_shows_evidence_history_and_shelves_and_takes_out_of_service(env):
    _leak(env)
    _web_sign_in(env)
    (a,) = _active(env)
    html = env.client.get("/breakers/1/alarms").text
    assert "not temperature-compensated" in html and 'class="evidence-plot"' in html
    assert "first-out" in html and f'data-alarm-id="{a["id"]}"' in html and "<polyline" in html
    r = env.client.post(f"/alarms/{a['id']}/shelve", data={"hours": "2", "reason": "crew on site",
                                                           "csrf_token": _csrf(html)}, follow_redirects=False)
    assert r.status_code == 303
    html = env.client.get("/breakers/1/alarms").text
    assert "Shelved until" in html and "crew on site" in html and "shelve by test-operator" in html
    bad = env.client.post(f"/alarms/{a['id']}/shelve", data={"hours": "2", "reason": "", "csrf_token": _csrf(html)})
    assert bad.status_code == 422
    r = env.client.post("/breakers/1/out-of-service", data={"reason": "WO-77", "csrf_token": _csrf(html)},
                        follow_redirects=False)
    assert r.status_code == 303
    assert "Out of service since" in env.client.get("/breakers/1").text
    # an operator cannot return it to service (that resets the baseline: admin)
    html = env.client.get("/breakers/1/alarms").text
    assert env.client.post("/breakers/1/return-to-service", data={"csrf_token": _csrf(html)}).status_code == 403


def test_web_upload_form_takes_a_temperature(env, breaker):
    _web_sign_in(env)
    cfg, dat = comtrade_pair(synth(breaker, "open", 7))
    html = env.client.get("/upload").text
    assert 'name="temperature_c"' in html
    files = [("files", ("a.cfg", cfg)), ("files", ("a.dat", dat))]
    bad = env.client.post("/upload", data={"breaker_id": "1", "temperature_c": "900", "csrf_token": _csrf(html)},
                          files=files)
    assert bad.status_code == 422 and "outside -60..100 C" in bad.text
    r = env.client.post("/upload", data={"breaker_id": "1", "temperature_c": "4,5", "csrf_token": _csrf(html)},
                        files=files, follow_redirects=False)
    assert r.status_code == 303, r.text
    op_id = int(r.headers["location"].rsplit("/", 1)[1])
    with env.Session() as s:
        row = s.get(OperationRow, op_id)
        assert (row.temperature_c, row.temperature_source) == (4.5, "upload")
    env.wait_fits()


def test_a_shelved_alarm_leaves_the_fleet_status_scada_and_iec61850_until_it_unshelves(env):
    """ISA-18.2 shelving suppresses the annunciation, not the record: SCADA's alarm level, the
    health status, the IEC 61850 view and the fleet page's alarm column drop the shelved alarm;
    the alarm list and the history keep it."""
    from service.iec61850.snapshot import OperatingTimeCache, breaker_views
    from service.storage.models import utcnow

    settings = _leak(env)
    (a,) = _active(env)
    tag = crud.list_breakers(env.Session())[0].tag

    def announced():
        env.client.app.state.scada_cache = None  # the points are cached for 1 s (SCADA_CACHE_S)
        points = {p["point"]: p["value"] for p in
                  env.client.get("/api/v1/scada/points", headers=env.h("reader")).json()}
        health = env.client.get("/api/v1/breakers/1/health", headers=env.h("reader")).json()
        with env.Session() as s:
            view = breaker_views(s, now=utcnow(), daq_timeout_s=60, drift_settings=settings,
                                 cache=OperatingTimeCache())[1]
        return points[f"{tag}.alarm_level"], health["status"], view.alarms

    level, status, iec = announced()
    assert level >= 1 and status == a["level"] and iec == {"DO": a["level"]}
    r = env.client.post(f"/api/v1/alarms/{a['id']}/shelve", json={"minutes": 60, "reason": "crew on site"},
                        headers=env.h("operator"))
    assert r.status_code == 200, r.text
    assert announced() == (0.0, "ok", {})
    env.client.app.state.scada_cache = None
    do = next(p for p in env.client.get("/api/v1/scada/points", headers=env.h("reader")).json()
              if p["point"] == f"{tag}.opening.DO")
    assert do["shelved_by"] == "test-operator" and do["shelved_until"] is not None  # the point says so
    _web_sign_in(env, "reader")
    fleet = env.client.get("/").text
    assert "buffer damping (DO) alarm shelved until" in fleet or "buffer damping (DO) warning shelved until" in fleet
    assert '<span class="muted">none</span>' not in fleet  # not "no alarm" while one is shelved
    assert "by test-operator" in fleet  # the page says until when and by whom
    page = env.client.get("/breakers/1").text
    assert 'data-shelved="DO"' in page and "by test-operator: crew on site" in page
    assert [x["id"] for x in _active(env)] == [a["id"]]  # still on the alarm list
    assert env.client.post(f"/api/v1/alarms/{a['id']}/unshelve", headers=env.h("operator")).status_code == 200
    assert announced() == (level, status, iec)
    env.client.app.state.scada_cache = None
    assert all(p["shelved_until"] is None for p in env.client.get("/api/v1/scada/points", headers=env.h("reader")).json())


def test_an_escalation_breaks_through_a_shelve_and_says_so_in_the_audit(env):
    from service.alarms import AlarmEvent
    from service.jobs.fit import apply_alarm_event
    from service.storage.models import AlarmRow, utcnow

    with env.Session() as s, s.begin():
        now = utcnow()
        warning = AlarmRow(breaker_id=1, parameter="BO", level="warning", state="raised", first_out=True, episode=1,
                           message="WARNING: BO", evidence={}, raised_at=now, updated_at=now,
                           shelved_until=now + timedelta(hours=2), shelved_at=now, shelved_by="op",
                           shelve_reason="known")
        s.add(warning)
    with env.Session() as s, s.begin():
        apply_alarm_event(s, breaker_id=1, event=AlarmEvent("escalated", "BO", "alarm", 1, None, utcnow(),
                                                            {"drift_direction": "falling"}))
    with env.Session() as s:
        row = s.scalar(select(AlarmRow).where(AlarmRow.parameter == "BO"))
        assert row.level == "alarm" and row.shelved_until <= utcnow()
        (audit,) = s.scalars(select(AlarmActionRow).where(AlarmActionRow.alarm_id == row.id))
    assert (audit.action, audit.by, audit.reason) == ("unshelve", "hvcb", "escalated to alarm")
