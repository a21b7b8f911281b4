"""The online calibration of the prognosis's interval on the breaker's own errors (issue 55 item 1)."""

from __future__ import annotations

import json
import math
from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

from service.alarms import DriftSettings, DriftState, FitObservation, update
from service.breaker_limits import ParameterLimit
from service.prognosis import calibration as cal_
from service.prognosis import prognose

T0 = datetime(2025, 1, 1, tzinfo=timezone.utc)
AHEAD = [1.0, 10.0, 100.0]


def forecast(cal, *, spread=1.0, crossing=None):
    """A flat level at 100 with 5/95 % at 100 -+ spread at every horizon."""
    return cal_.issue(cal, AHEAD, [100.0] * 3, [100.0 - spread] * 3, [100.0 + spread] * 3, crossing)


def test_pit_of_the_split_normal():
    assert cal_.pit(100.0, 100.0, 99.0, 102.0, 0.0)[0] == pytest.approx(0.5)
    assert cal_.pit(99.0, 100.0, 99.0, 102.0, 0.0)[0] == pytest.approx(0.05, abs=1e-6)
    assert cal_.pit(102.0, 100.0, 99.0, 102.0, 0.0)[0] == pytest.approx(0.95, abs=1e-6)
    u, v_lo, v_hi = cal_.pit(99.0, 100.0, 99.0, 102.0, 1.0 / cal_.Z_ALPHA)
    assert 0.05 < u < 0.5 and v_lo == pytest.approx(0.5) and v_hi == pytest.approx(0.8)


def test_a_breaker_that_surprises_low_widens_the_early_crossing():
    cal = forecast(cal_.Calibration(key="reset"), spread=1.0)
    for i in range(60):  # the level falls away from the forecast: a fit far below its 5 % one in three
        cal = cal_.score(cal, 100.0 - 2.0 * (i % 3 == 0), 0.1, i + 1)
    early, late = cal_.levels(cal, "falling")
    assert early < cal_.ALPHA  # the earliest crossing is read further out in its tail
    _, late_r = cal_.levels(cal, "rising")
    assert late_r > 1 - cal_.ALPHA  # rising: a level lower than forecast is a later crossing


def test_a_breaker_that_never_surprises_narrows_the_interval():
    cal = forecast(cal_.Calibration(key="reset"), spread=3.0)
    for i in range(60):
        cal = cal_.score(cal, 100.0 + 0.05 * ((-1) ** i), 0.1, i + 1)
    early, late = cal_.levels(cal, "falling")
    assert early > cal_.ALPHA and late < 1 - cal_.ALPHA


def test_too_few_scores_leave_the_levels_alone():
    cal = forecast(cal_.Calibration(key="reset"))
    for i in range(cal_.MIN_SCORES - 5):
        cal = cal_.score(cal, 90.0, 0.1, i + 1)
    assert cal_.levels(cal, "falling") == (cal_.ALPHA, 1 - cal_.ALPHA)


def test_a_fit_is_scored_once():
    cal = forecast(cal_.Calibration(key="reset"))
    once = cal_.score(cal, 99.0, 0.1, 7)
    assert cal_.score(once, 99.0, 0.1, 7) is once and once.fits == 1


def test_a_crossing_sooner_than_its_interval_widens_its_early_side():
    cal = forecast(cal_.Calibration(key="reset"), crossing=(50.0, 200.0))
    for i in range(10):
        cal = cal_.score(cal, 100.0, 0.1, i + 1)
    cal = cal_.crossed(cal)  # 10 openings, its 5 % said 50
    assert cal.crossing["n"] == 1 and cal.crossing["lo"] < 0 and cal.crossing["hi"] > 0
    assert cal_.levels(cal, "falling")[0] < cal_.ALPHA and not cal.crossing["pending"]


def test_the_state_goes_through_json_and_restarts_with_another_history():
    cal = forecast(cal_.Calibration(key="reset"))
    for i in range(30):
        cal = cal_.score(cal, 99.5 - 0.05 * i, 0.2, i + 1)
    back = cal_.Calibration.from_dict(json.loads(json.dumps(cal.to_dict())), key="reset")
    assert back == cal
    fresh = cal_.Calibration.from_dict(cal.to_dict(), key="maintenance 2025-06-01T00:00:00+00:00")
    assert fresh.fits == 0 and not fresh.forecasts and fresh.key.startswith("maintenance")


def _leak(n: int, onset: int, rate: float, seed: int = 3):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        v = 39.5 * (1.0 - rate * max(0, i - onset)) * (1 + 0.01 * rng.standard_normal())
        out.append(FitObservation(operation_id=i + 1, time=T0 + timedelta(days=i), value=v,
                                  ci95=(v - 0.4, v + 0.4), temperature=None))
    return out


def test_prognose_reads_the_crossing_at_the_calibrated_levels():
    obs = _leak(140, 100, 0.004)
    settings, state = DriftSettings(), DriftState.new("DO", DriftSettings())
    for o in obs:
        state, _ = update(state, o, settings)
    plain = prognose(state, obs, ParameterLimit(min_change=-0.25))
    wide = cal_.Calibration(key="reset")
    wide.bands[20].n, wide.bands[20].a_lo, wide.bands[20].a_hi = 100, 0.005, 0.005
    wide.bands[20].v_lo = wide.bands[20].v_hi = 0.9
    calibrated = prognose(state, obs, ParameterLimit(min_change=-0.25), calibration=wide)
    q, qc = plain.operations_to_limit, calibrated.operations_to_limit
    assert qc.median == q.median and qc.p05 < q.p05 and (q.p95 is None or qc.p95 is None or qc.p95 > q.p95)
    assert calibrated.calibration["levels"][0] < 0.05 and len(plain.forecast["median"]) == len(cal_.FORECAST_AHEAD)


def test_a_restart_in_the_middle_of_a_history_gives_the_same_next_interval():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
    from prognosis_driver import Case, run_case

    obs = _leak(260, 120, 0.003)
    case = Case(name="leak", parameter="DO", limit=ParameterLimit(min_change=-0.25), obs=obs, stops=[200, 240],
                fractions=[0.5, 0.75], due=[160])
    plain = run_case(case, DriftSettings())
    restarted = run_case(case, DriftSettings(), restart_at=180)  # between the due prognosis and the first question
    assert plain[1]["calibration"]["scores"]["20"]["n"] > 0  # the calibration had something to carry
    assert [r["pred"] for r in restarted] == [r["pred"] for r in plain]
    assert [r["calibration"] for r in restarted] == [r["calibration"] for r in plain]
    uncalibrated = run_case(case, DriftSettings(), calibrate=False)
    assert math.isfinite(uncalibrated[0]["pred"][0])
