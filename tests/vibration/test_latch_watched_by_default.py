"""Issue 56 item 1: the trip latch is watched by default. Served with the shipped settings
(config/default.toml) and the shipped reference breaker file, a latch that sticks a little more
each opening alarms within 15 openings of the onset and gets a prognosis; a healthy one raises
nothing; a breaker whose captures carry no vibration is neither alarming nor "unknown" because of
it; one breaker can have the latch turned off, with its thresholds designed for its own sides."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

from service.alarms import DriftState
from service.alarms.actions import health_status
from service.alarms.design import cusum_arl
from service.alarms.settings import DriftSettings
from service.breaker_file import parse_breaker_text
from service.jobs.fit import drift_status, update_drift
from service.jobs.prognosis import breaker_prognoses
from service.settings import load_settings
from service.storage import crud
from service.storage.db import cached_engine, session_factory, upgrade
from tests.conftest import BREAKER_FILE, REPO
from tests.fit_rows import store_fit

SHIPPED = load_settings(REPO / "config" / "default.toml").drift_settings
T0 = datetime(2026, 1, 1, tzinfo=timezone.utc)
ONSET, PER_OPENING_S, HEALTHY_S = 30, 0.02e-3, 1.2e-3  # bench/vibration_series.py's growing latch


def test_the_shipped_settings_watch_the_latch_beside_do_and_bo():
    assert SHIPPED.watched == {"DO": "falling", "BO": "both", "latch_time_s": "rising"}
    assert DriftSettings().watched == SHIPPED.watched  # the code's default is the file's


def test_the_four_sides_share_the_breakers_designed_rate():
    # each one-sided CUSUM's in-control run length, from its threshold: 4 sides together give the
    # designed warnings and alarms per 10 000 operations of the breaker
    for h, rate in ((SHIPPED.h_warning, SHIPPED.design_false_warnings_per_10k),
                    (SHIPPED.h_alarm, SHIPPED.design_false_alarms_per_10k)):
        per_side = 1e4 / cusum_arl(0.0, k=SHIPPED.k, h=h, z_cap=SHIPPED.z_cap)
        assert SHIPPED.sides == 4
        assert SHIPPED.sides * per_side == pytest.approx(rate, rel=0.01)  # the chain steps with h (test_design)
    two = DriftSettings(watched={"DO": "falling", "BO": "both"})
    assert SHIPPED.h_warning > two.h_warning and SHIPPED.h_alarm > two.h_alarm


def test_one_breaker_can_have_the_latch_off_and_its_thresholds_follow():
    s = DriftSettings(breakers={"bay-7": {"latch_time_s": "off"}})
    bay7 = s.for_breaker("bay-7")
    assert bay7.watched == {"DO": "falling", "BO": "both"}
    two = DriftSettings(watched={"DO": "falling", "BO": "both"})
    assert (bay7.h_warning, bay7.h_alarm) == pytest.approx((two.h_warning, two.h_alarm))
    assert s.for_breaker("bay-8") is s and s.for_breaker("bay-8").sides == 4
    with pytest.raises(ValueError, match="bay-9.*every watched parameter off"):
        DriftSettings(breakers={"bay-9": {"DO": "off", "BO": "off", "latch_time_s": "off"}}).for_breaker("bay-9")
    with pytest.raises(ValueError, match="alarm direction breakers.bay-7.latch_time_s must be one of"):
        DriftSettings.from_mapping({"breakers": {"bay-7": {"latch_time_s": "sideways"}}})


def test_the_reference_breaker_file_has_the_latch_limit_from_its_opening_time():
    limits = parse_breaker_text(BREAKER_FILE.read_text(), source=str(BREAKER_FILE)).limits
    opening = parse_breaker_text(BREAKER_FILE.read_text(), source="b").characteristic_limits
    assert limits.root["latch_time_s"].max == pytest.approx(2.3e-3)
    # the derivation the file's comment gives: the healthy 1.2 ms plus the opening time's margin
    margin = opening.open["operating_time_s"].max - 0.0112
    assert limits.root["latch_time_s"].max == pytest.approx(HEALTHY_S + margin, abs=0.05e-3)


@pytest.fixture
def session_maker(tmp_path):
    url = f"sqlite:///{tmp_path / 'hvcb.sqlite3'}"
    upgrade(url)
    Session = session_factory(cached_engine(url))
    cam = (BREAKER_FILE.parent / "reference-252kV.cam.csv").read_text()
    with Session() as s, s.begin():  # the shipped breaker file as it is
        crud.upsert_breaker(s, name="reference-252kV", tag="Q1", breaker_file=BREAKER_FILE.read_text(),
                            cam_file_name="reference-252kV.cam.csv", cam_table=cam)
    return Session


def _store(Session, i, latch, rng):
    do, bo = 39.5 * (1 + rng.normal(0, 0.01)), 4806.0 * (1 + rng.normal(0, 0.01))
    chars = ({"latch_time_s": None, "latch_time_reason": "no vibration channel in the capture",
              "vibration_events": []} if latch is None else
             {"latch_time_s": latch, "vibration_events": [
                 {"name": "first_shock", "t_s": -latch, "peak_g": 30.0, "clipped": False},
                 {"name": "latch_release", "t_s": -0.4e-3, "peak_g": 400.0, "clipped": False}]})
    with Session() as s, s.begin():
        store_fit(s, key=f"op{i}", breaker_id=1, occurred_at=T0 + timedelta(hours=i), result={
            "parameters": {"AO": 3424.0, "BO": bo, "DO": do, "EO": 3950.0},
            "ci95": {"DO": [do - 0.3, do + 0.3], "BO": [bo - 40, bo + 40]}, "identifiable": True,
            "characteristics": chars})
        return update_drift(s, breaker_id=1, settings=SHIPPED)


def test_served_with_the_shipped_settings_a_sticking_latch_alarms_within_15_openings(session_maker):
    rng = np.random.default_rng(3)
    alarmed = None
    for i in range(ONSET + 20):
        latch = HEALTHY_S * (1 + rng.normal(0, 0.02)) + max(0, i - ONSET + 1) * PER_OPENING_S
        events = _store(session_maker, i, latch, rng)
        if alarmed is None and any(e.parameter == "latch_time_s" and e.level == "alarm"
                                   and e.kind in ("raised", "escalated") for e in events):
            alarmed = i
    assert alarmed is not None and ONSET <= alarmed < ONSET + 15, alarmed
    with session_maker() as s:
        progs = {p.parameter: p for p in breaker_prognoses(s, breaker=crud.get_breaker(s, breaker_id=1),
                                                         settings=SHIPPED)}
    assert progs["latch_time_s"].status == "ok", progs["latch_time_s"]
    assert progs["latch_time_s"].operations_to_limit.median is not None


def test_served_with_the_shipped_settings_a_healthy_latch_raises_nothing(session_maker):
    rng = np.random.default_rng(7)
    raised = []
    for i in range(ONSET + 20):  # as long as the sticking one's history
        raised += [e for e in _store(session_maker, i, HEALTHY_S * (1 + rng.normal(0, 0.02)), rng)
                   if e.parameter == "latch_time_s"]
    assert raised == []


def test_captures_without_vibration_leave_the_latch_quiet_and_the_breaker_ok(session_maker):
    rng = np.random.default_rng(9)
    events = []
    for i in range(SHIPPED.baseline_n + 5):
        events += _store(session_maker, i, None, rng)
    assert not [e for e in events if e.parameter == "latch_time_s"]
    with session_maker() as s:
        assert drift_status(s, breaker_id=1, settings=SHIPPED) == "ok"


def test_a_never_fed_parameter_does_not_keep_the_status_unknown_but_no_fit_at_all_does():
    fresh = [DriftState.new(p, SHIPPED) for p in SHIPPED.watched]
    assert health_status(fresh) == "unknown"
    monitoring = [DriftState(parameter="DO", phase="monitoring", last_operation_id=9),
                  DriftState(parameter="BO", phase="monitoring", last_operation_id=9),
                  DriftState.new("latch_time_s", SHIPPED)]
    assert health_status(monitoring) == "ok"
    collecting = [*monitoring[:2], DriftState(parameter="latch_time_s", collected=((1, 1e-3, None, None),),
                                               last_operation_id=1)]
    assert health_status(collecting) == "unknown"  # a latch being learnt is still learnt


def test_served_a_breaker_with_its_latch_turned_off_raises_nothing_on_it(session_maker):
    from service.storage.models import DriftStateRow
    from tests.fit_rows import store_fit

    off = DriftSettings(breakers={"reference-252kV": {"latch_time_s": "off"}})
    rng = np.random.default_rng(3)
    events = []
    for i in range(ONSET + 20):  # the sticking latch that alarms with the shipped settings
        latch = HEALTHY_S * (1 + rng.normal(0, 0.02)) + max(0, i - ONSET + 1) * PER_OPENING_S
        chars = {"latch_time_s": latch, "vibration_events": []}
        with session_maker() as s, s.begin():
            store_fit(s, key=f"off{i}", breaker_id=1, occurred_at=T0 + timedelta(hours=i), result={
                "parameters": {"AO": 3424.0, "BO": 4806.0, "DO": 39.5 * (1 + rng.normal(0, 0.01)), "EO": 3950.0},
                "identifiable": True, "characteristics": chars})
            events += update_drift(s, breaker_id=1, settings=off)
    assert not [e for e in events if e.parameter == "latch_time_s"]
    with session_maker() as s:
        assert s.get(DriftStateRow, (1, "latch_time_s")) is None  # never fed to a detector
        assert drift_status(s, breaker_id=1, settings=off) in ("ok", "learning")
