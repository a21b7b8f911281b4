"""D6: a capture dated more than a day after its arrival is kept and flagged clock suspect;
it never becomes the latest, never reaches SCADA and never enters the drift baseline."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

from service.jobs.ingest import clock_suspect
from service.storage import crud

from .conftest import synth
from .test_d15_session_rotation import sign_in


def test_the_rule_is_one_day_ahead_and_never_behind():
    now = datetime(2026, 11, 25, tzinfo=timezone.utc)
    assert not clock_suspect(now + timedelta(hours=23), now, 86400.0)
    assert clock_suspect(now + timedelta(hours=25), now, 86400.0)
    assert not clock_suspect(now - timedelta(days=3650), now, 86400.0)  # old recordings are fine


def test_a_capture_dated_2099_is_kept_flagged_and_never_latest(env, breaker):
    monitor = env.app.state.monitor
    true_time = datetime.now(timezone.utc) - timedelta(hours=1)
    good = monitor.ingest(synth(breaker, "open", seed=1, start_time=true_time), breaker_id=1, operation="open")
    future = monitor.ingest(synth(breaker, "open", seed=2, scale={"DO": 1.6}, start_time=datetime(2099, 1, 1,
                            tzinfo=timezone.utc)), breaker_id=1, operation="open", source="daq")
    env.wait_fits(2)

    with env.Session() as s:
        assert crud.get_operation(s, operation_id=future.operation_id).clock_suspect
        assert not crud.get_operation(s, operation_id=good.operation_id).clock_suspect
        latest = crud.latest_fit(s, breaker_id=1, kind="open")
        assert latest.operation_id == good.operation_id
        assert crud.latest_good_fit(s, breaker_id=1, kind="open").operation_id == good.operation_id
        history = crud.good_parameter_history(s, breaker_id=1, name="DO")
        assert {pv.operation_id for pv in history} == {good.operation_id}  # not in the drift baseline
        good_do = latest.parameters["DO"]

    points = {p["point"]: p for p in env.client.get("/api/v1/scada/points", headers=env.h("reader")).json()}
    do_point = next(p for name, p in points.items() if name.endswith(".opening.DO"))
    assert do_point["value"] == good_do and not do_point["timestamp"].startswith("2099")

    ops = env.client.get("/api/v1/breakers/1/operations", headers=env.h("reader"),
                         params={"clock_suspect": "true"}).json()
    assert [o["id"] for o in ops] == [future.operation_id] and ops[0]["clock_suspect"] is True
    ops = env.client.get("/api/v1/breakers/1/operations", headers=env.h("reader"),
                         params={"clock_suspect": "false"}).json()
    assert [o["id"] for o in ops] == [good.operation_id]
    trend = env.client.get("/api/v1/breakers/1/parameters", params={"name": "DO"}, headers=env.h("reader")).json()
    assert [p["operation_id"] for p in trend["points"]] == [good.operation_id]

    health = env.client.get("/healthz", headers=env.h("reader")).json()
    assert health["clock_suspect"] == {"1": 1}  # the DAQ clock jump is visible to the operator

    sign_in(env.client, env.keys["reader"])
    page = env.client.get("/breakers/1").text
    assert "clock suspect" in page
    op_page = env.client.get(f"/operations/{future.operation_id}").text
    assert 'id="clock-suspect"' in op_page
