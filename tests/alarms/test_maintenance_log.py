"""The engineer's maintenance log (issue 50 item 4): the pure restart, the API on SQLite and
PostgreSQL, the breaker page's card and the report's block."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest
from sqlalchemy import select

from service.alarms import DriftSettings, DriftState
from service.alarms.maintenance import KINDS, MaintenanceError, restart, touches
from tests.fit_rows import store_leak

URL = "/api/v1/breakers/{}/maintenance"
T = datetime(2026, 3, 1, 9, 0, tzinfo=timezone.utc)


def test_each_kind_touches_its_parameters_and_an_unknown_kind_is_refused_in_words():
    assert touches("buffer refilled", "DO") and not touches("buffer refilled", "BO")
    assert touches("spring replaced", "BO") and not touches("spring replaced", "DO")
    assert touches("latch lubricated", "latch_time_s")
    assert all(touches("sensor remounted or recalibrated", p) for p in ("DO", "BO", "AC", "latch_time_s"))
    with pytest.raises(MaintenanceError, match='one of "buffer refilled"'):
        touches("oil changed", "DO")
    assert set(KINDS) == {"buffer refilled", "latch lubricated", "sensor remounted or recalibrated",
                          "spring replaced"}


def test_restart_clears_the_alarm_and_learns_a_new_baseline_from_the_work_on():
    active = DriftState(parameter="DO", level="alarm", episode=3, last_operation_id=40, last_time=T,
                        s_falling=12.0)
    fresh, events = restart(active, kind="buffer refilled", done_at=T - timedelta(days=1), by="J. Smith")
    assert fresh.phase == "baseline" and fresh.level == "none" and fresh.episode == 3
    assert fresh.last_time == T - timedelta(days=1) and fresh.last_operation_id == 0
    assert [e.kind for e in events] == ["cleared"] and "buffer refilled by J. Smith" in events[0].reason
    other = DriftState(parameter="BO", level="alarm", last_time=T)
    same, none = restart(other, kind="buffer refilled", done_at=T, by="J. Smith")
    assert same is other and none == []
    with pytest.raises(MaintenanceError, match="timezone-aware"):
        restart(active, kind="buffer refilled", done_at=datetime(2026, 3, 1), by="x")


def test_logging_a_refill_restarts_do_and_its_prognosis_and_leaves_bo(env):
    from service.storage.models import AlarmRow, DriftStateRow

    t0 = datetime.now(timezone.utc) - timedelta(hours=2)
    store_leak(env.Session, env.settings.drift_settings, t0=t0, step=timedelta(seconds=1))
    with env.Session() as s:
        assert s.scalar(select(AlarmRow).where(AlarmRow.parameter == "DO", AlarmRow.state != "cleared")) is not None
        bo_before = s.get(DriftStateRow, (1, "BO")).state
    assert env.client.get(URL.format(1), headers=env.h("reader")).json() == []
    body = {"kind": "buffer refilled", "done_by": "J. Smith", "note": "oil topped up, seals checked",
            "done_at": (t0 + timedelta(seconds=28.5)).isoformat()}
    assert env.client.post(URL.format(1), json=body, headers=env.h("reader")).status_code == 403
    r = env.client.post(URL.format("reference-252kV"), json=body, headers=env.h("operator"))
    assert r.status_code == 201, r.text
    e = r.json()
    assert e["kind"] == "buffer refilled" and e["parameters"] == ["DO", "EO"] and e["done_by"] == "J. Smith"
    assert e["recorded_by"].endswith("(api)")
    with env.Session() as s:
        # DO's alarm is cleared; its detector learns a new baseline from the 3 fits after the refill
        assert s.scalar(select(AlarmRow).where(AlarmRow.parameter == "DO", AlarmRow.state != "cleared")) is None
        do = DriftState.from_dict(s.get(DriftStateRow, (1, "DO")).state)
        assert do.phase == "baseline" and len(do.collected) == 3
        assert s.get(DriftStateRow, (1, "BO")).state == bo_before  # untouched
    p = env.client.get(f"/api/v1/breakers/1/prognosis", headers=env.h("reader")).json()
    do_p = next(x for x in p["parameters"] if x["parameter"] == "DO")
    assert do_p["status"] == "no trend" and "learning the baseline (3 fits" in do_p["reason"]
    listed = env.client.get(URL.format(1), headers=env.h("reader")).json()
    assert [x["id"] for x in listed] == [e["id"]] and listed[0]["note"] == "oil topped up, seals checked"


@pytest.mark.parametrize("body, words", [
    ({"kind": "oil changed", "done_by": "x"}, "kind"),
    ({"kind": "spring replaced", "done_by": "x", "done_at": "2999-01-01T00:00:00Z"}, "in the future"),
    ({"kind": "spring replaced", "done_by": "x", "done_at": "2026-01-01T00:00:00"}, "time zone"),
    ({"kind": "spring replaced", "done_by": ""}, "done_by"),
])
def test_bad_entries_are_refused_in_words(env, body, words):
    r = env.client.post(URL.format(1), json=body, headers=env.h("operator"))
    assert r.status_code == 422 and words in r.text, r.text
    assert env.client.get(URL.format(1), headers=env.h("reader")).json() == []
    assert env.client.get(URL.format("nope"), headers=env.h("reader")).status_code == 404


def test_the_log_is_in_the_openapi_and_on_the_breaker_page_and_in_the_report(env):
    spec = env.client.get("/openapi.json").json()
    ops = spec["paths"]["/api/v1/breakers/{name}/maintenance"]
    assert {"200", "401", "403", "404"} <= set(ops["get"]["responses"]) and "201" in ops["post"]["responses"]
    r = env.client.post(URL.format(1), json={"kind": "sensor remounted or recalibrated", "done_by": "A. Jones"},
                        headers=env.h("operator"))
    assert r.status_code == 201 and r.json()["parameters"] == ["*"]
    from service.reports.content import gather
    from service.storage.models import BreakerRow

    with env.Session() as s:
        c = gather(s, breaker=s.get(BreakerRow, 1), settings=env.settings.drift_settings)
        assert [(e.kind, e.done_by) for e in c.maintenance] == [("sensor remounted or recalibrated", "A. Jones")]
        from service.storage.maintenance import restart_time

        done = datetime.fromisoformat(r.json()["done_at"].replace("Z", "+00:00"))
        assert restart_time(s, 1, "DO") == done and restart_time(s, 1, "BO") == done  # "*": every parameter


def test_an_operator_logs_work_on_the_breaker_page_and_a_reader_sees_it_without_the_form(env):
    from tests.web_forms import page_csrf, sign_in

    sign_in(env.client, env.keys["operator"])
    page = env.client.get("/breakers/1")
    assert page.status_code == 200 and 'id="maintenance-log"' in page.text and "No maintenance logged." in page.text
    assert 'id="maintenance-form"' in page.text and all(f'<option value="{k}">' in page.text for k in KINDS)
    r = env.client.post("/breakers/1/maintenance", data={
        "csrf_token": page_csrf(env.client, "/breakers/1"), "kind": "spring replaced", "done_by": "K. Lee",
        "done_at": "2026-02-01T08:30", "note": "new opening spring, setting 0 steps"}, follow_redirects=False)
    assert r.status_code == 303, r.text
    page = env.client.get("/breakers/1").text
    row = page[page.index('data-maintenance-id='):]
    assert "2026-02-01 08:30" in row and "spring replaced" in row and "K. Lee" in row and "AO, BO, AC, CC, DC" in row
    listed = env.client.get(URL.format(1), headers=env.h("reader")).json()
    assert listed[0]["recorded_by"].endswith("(web)") and listed[0]["done_at"].startswith("2026-02-01T08:30")
    env.client.cookies.clear()
    sign_in(env.client, env.keys["reader"])
    page = env.client.get("/breakers/1").text
    assert "K. Lee" in page and 'id="maintenance-form"' not in page
