"""The latch time as a watched drift quantity: read from the characteristics, its cause and action in
words, its IEC 61850 and REST SCADA points."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest

import service.iec61850.points as pm
from service.alarms import observations_from_fit
from service.alarms.settings import DriftSettings
from service.findings import action, likely_cause

NOW = datetime(2026, 3, 1, tzinfo=timezone.utc)


def test_a_watched_characteristic_becomes_an_observation_and_a_null_one_none():
    settings = DriftSettings(watched={"DO": "falling", "latch_time_s": "rising"})
    fit = {"parameters": {"DO": 39.0}, "ci95": {"DO": [38.0, 40.0]}, "characteristics": {"latch_time_s": 1.3e-3}}
    obs = observations_from_fit(fit, operation_id=3, time=NOW, settings=settings)
    assert obs["latch_time_s"].value == pytest.approx(1.3e-3) and obs["DO"].value == 39.0
    fit["characteristics"] = {"latch_time_s": None, "latch_time_reason": "no vibration channel"}
    assert "latch_time_s" not in observations_from_fit(fit, operation_id=4, time=NOW, settings=settings)


def test_the_slow_latch_in_words():
    assert likely_cause("latch_time_s", "rising").startswith("the trip latch is slow")
    assert action("latch_time_s") == "The trip latch is slow: lubricate or clean the latch."


def test_iec61850_serves_the_latch_time_and_its_drift_alarm():
    dev = pm.logical_device("Q1", "ref", ["DO", "latch_time_s"])
    names = {o.name for o in dev.objects}
    assert {"LatTm", "LatTmWrn", "LatTmAlm"} <= names and not any("_" in n for n in names)
    opening = pm.FitView(parameters={"DO": 39.0}, identifiable=True, occurred_at=NOW - timedelta(minutes=5),
                         latch_time_s=1.4e-3)
    view = pm.BreakerView(name="ref", tag="Q1", fits={"open": opening}, alarms={"latch_time_s": "alarm"})
    v = pm.values(dev, view, now=NOW, stale_after_s=3600)
    assert v["SOPM1.LatTm"].value == pytest.approx(1.4e-3) and v["SOPM1.LatTm"].quality == pm.GOOD
    assert v["SOPM1.LatTmAlm"].value is True and v["SOPM1.Health"].value == pm.HEALTH["alarm"]
    none = pm.values(dev, pm.BreakerView(name="ref", tag="Q1", fits={"open": pm.FitView({}, True, NOW)}),
                     now=NOW, stale_after_s=3600)
    assert none["SOPM1.LatTm"].quality == pm.INVALID
