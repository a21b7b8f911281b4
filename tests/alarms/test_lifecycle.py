"""The operators' state machine: shelve (time-limited, with a reason), unshelve, acknowledge,
out of service and back, first-out order. Every action names who, when and why."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest

from service.alarms import lifecycle as lc

NOW = datetime(2026, 3, 1, 12, tzinfo=timezone.utc)


def raised(**kw) -> lc.AlarmView:
    return lc.AlarmView(id=7, state="raised", **kw)


def test_shelve_hides_for_the_stated_time_then_ends_by_itself():
    a, act = lc.shelve(raised(), by="op", now=NOW, duration=timedelta(hours=8), reason="crew on site")
    assert a.shelved(NOW) and a.shelved(NOW + timedelta(hours=7, minutes=59))
    assert not a.shelved(NOW + timedelta(hours=8))
    assert (act.action, act.by, act.at, act.reason, act.until, act.alarm_id) == (
        "shelve", "op", NOW, "crew on site", NOW + timedelta(hours=8), 7)


def test_reshelving_replaces_the_end_and_unshelve_ends_it_now():
    a, _ = lc.shelve(raised(), by="op", now=NOW, duration=timedelta(hours=8), reason="crew on site")
    a, act = lc.shelve(a, by="op2", now=NOW + timedelta(hours=1), duration=timedelta(hours=1), reason="shorter")
    assert a.shelved_until == NOW + timedelta(hours=2) and a.shelved_by == "op2" and act.action == "shelve"
    a, act = lc.unshelve(a, by="op", now=NOW + timedelta(hours=1, minutes=30))
    assert not a.shelved(NOW + timedelta(hours=1, minutes=30)) and act.action == "unshelve"
    with pytest.raises(lc.LifecycleError, match="not shelved"):
        lc.unshelve(a, by="op", now=NOW + timedelta(hours=1, minutes=31))


@pytest.mark.parametrize("alarm, kw, message", [
    (raised(), {"reason": ""}, "give a reason"),
    (raised(), {"reason": "ok", "by": " "}, "name of who"),
    (raised(), {"duration": timedelta(days=8)}, "at most 7 days"),
    (raised(), {"duration": timedelta(0)}, "must be positive"),
    (lc.AlarmView(id=7, state="cleared"), {}, "only an active alarm can be shelved"),
    (raised(), {"now": datetime(2026, 3, 1)}, "timezone-aware"),
])
def test_shelve_refuses_in_words(alarm, kw, message):
    args = {"by": "op", "now": NOW, "duration": timedelta(hours=1), "reason": "crew on site", **kw}
    with pytest.raises(lc.LifecycleError, match=message):
        lc.shelve(alarm, **args)


def test_a_cleared_alarm_is_never_shelved_even_if_its_time_is_not_up():
    a = lc.AlarmView(id=1, state="cleared", shelved_until=NOW + timedelta(hours=1))
    assert not a.shelved(NOW)


def test_acknowledge_transitions():
    a, act = lc.acknowledge(raised(), by="op", now=NOW, comment="seen")
    assert a.state == "acknowledged" and act.reason == "seen"
    with pytest.raises(lc.LifecycleError, match="already acknowledged"):
        lc.acknowledge(a, by="op", now=NOW)
    with pytest.raises(lc.LifecycleError, match="nothing to acknowledge"):
        lc.acknowledge(lc.AlarmView(id=1, state="cleared"), by="op", now=NOW)


def test_out_of_service_and_back():
    svc = lc.ServiceView()
    assert svc.in_service
    with pytest.raises(lc.LifecycleError, match="give a reason"):
        lc.take_out_of_service(svc, by="op", now=NOW, reason="")
    svc, act = lc.take_out_of_service(svc, by="op", now=NOW, reason="WO-1234")
    assert not svc.in_service and act.action == "out_of_service" and act.reason == "WO-1234"
    with pytest.raises(lc.LifecycleError, match="already out of service"):
        lc.take_out_of_service(svc, by="op", now=NOW, reason="again")
    back, act = lc.return_to_service(svc, by="admin", now=NOW + timedelta(days=1))
    assert back.in_service and act.action == "return_to_service" and "maintenance since" in act.reason
    with pytest.raises(lc.LifecycleError, match="is in service"):
        lc.return_to_service(back, by="admin", now=NOW)


def test_first_out_is_the_alarm_raised_while_nothing_else_was_active():
    h = timedelta(hours=1)
    flags = lc.first_out([(1, NOW, NOW + 3 * h),       # first of a cascade
                          (2, NOW + h, None),           # raised while 1 was active
                          (3, NOW + 5 * h, None),       # 2 still active
                          (4, NOW + 2 * h, NOW + 4 * h)])
    assert flags == {1: True, 2: False, 4: False, 3: False}
    assert lc.first_out([(5, NOW, NOW + h), (6, NOW + 2 * h, None)]) == {5: True, 6: True}
