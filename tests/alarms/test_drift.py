"""Drift detector behaviour: outliers, hysteresis, lifecycle, baseline reset, state, bad input."""

from __future__ import annotations

import json
import math
from datetime import datetime, timedelta

import pytest
from scipy import special

from histories import BO_NOMINAL, DO_NOMINAL, T0, first_alarm, fit_history
from service.alarms import (DriftSettings, DriftState, FitObservation, acknowledge, health_status,
                            observations_from_fit, replay, reset_baseline, t_for_score, update)
from service.alarms.design import cusum_arl

SETTINGS = DriftSettings()


def obs(op: int, value: float, se: float = 0.0) -> FitObservation:
    return FitObservation(operation_id=op, time=T0 + timedelta(hours=op), value=value, stderr=se)


def flat_baseline(parameter="DO", mean=DO_NOMINAL, sd=0.4) -> DriftState:
    """A monitored state whose baseline is exactly (mean, sd): fits alternate mean +/- a."""
    n = SETTINGS.baseline_n
    a = sd * math.sqrt((n - 1) / n)  # sample sd (ddof=1) of n values at mean +/- a is sd
    state, _ = replay([obs(i, mean + (a if i % 2 else -a)) for i in range(1, n + 1)], SETTINGS,
                      parameter=parameter)
    assert state.phase == "monitoring"
    assert state.baseline.mean == pytest.approx(mean) and state.baseline.sd == pytest.approx(sd)
    return state


def value_for_score(state: DriftState, score: float) -> float:
    """The fit value whose CUSUM input (normal score, se = 0) is ``score`` against the state's
    current baseline model (which keeps learning while the CUSUM is quiet)."""
    mean, var = state.model.predict(None, 0.0)
    return mean + t_for_score(score, state.model.dof) * math.sqrt(var)


def feed(state, scores, start_op):
    events, trace = [], []
    for i, u in enumerate(scores):
        state, new = update(state, obs(start_op + i, value_for_score(state, u)), SETTINGS)
        events += new
        trace.append(state.statistic)
    return state, events, trace


# --- outliers -------------------------------------------------------------------------------

def test_an_isolated_extreme_fit_is_held_then_ignored():
    state = flat_baseline()
    state, events = update(state, obs(21, DO_NOMINAL * 0.70), SETTINGS)
    assert events == [] and state.held[0] == 21 and state.statistic == 0
    state, events = update(state, obs(22, DO_NOMINAL), SETTINGS)
    assert events == [] and state.held is None and state.outliers_ignored == 1
    assert state.statistic == 0


def test_a_confirmed_step_counts_both_fits_capped_at_z_cap_minus_k():
    """Two capped fits stay below the warning threshold (so two gross fit errors in a row, 1 in
    10 000 fits at 1 % outliers, raise nothing); a third consistent one raises the alarm."""
    state = flat_baseline()
    assert 2 * (SETTINGS.z_cap - SETTINGS.k) < SETTINGS.h_warning
    assert 3 * (SETTINGS.z_cap - SETTINGS.k) >= SETTINGS.h_alarm
    state, _ = update(state, obs(21, DO_NOMINAL * 0.70), SETTINGS)
    state, events = update(state, obs(22, DO_NOMINAL * 0.70), SETTINGS)
    assert state.s_falling == pytest.approx(2 * (SETTINGS.z_cap - SETTINGS.k)) and events == []
    state, events = update(state, obs(23, DO_NOMINAL * 0.70), SETTINGS)
    assert [(e.kind, e.level) for e in events] == [("raised", "alarm")]
    assert events[0].evidence["operation_ids"] == [21, 22, 23]


def test_an_outlier_next_to_a_leaning_fit_is_still_held():
    """A gross error jumps away from its neighbours' scores; a drift moves them together."""
    state = flat_baseline()
    state, _, _ = feed(state, [-2.5], 21)
    state, events = update(state, obs(22, DO_NOMINAL * 0.70), SETTINGS)
    assert state.held is not None and state.held[0] == 22 and events == []
    state, _, _ = feed(state, [-2.0], 23)
    assert state.held is None and state.outliers_ignored == 1
    assert state.s_falling == pytest.approx((2.5 - SETTINGS.k) + (2.0 - SETTINGS.k))


@pytest.mark.parametrize("parameter, nominal, rel", [
    ("DO", DO_NOMINAL, -0.30), ("BO", BO_NOMINAL, -0.30), ("BO", BO_NOMINAL, +0.30)])
def test_a_single_outlier_fit_never_raises_an_alarm(parameter, nominal, rel):
    """One fit 30 % off, at every monitored position of 20 noisy control histories."""
    checked = 0
    for seed in range(3):
        clean = fit_history(seed + 7000, nominal=nominal)
        if first_alarm(replay(clean, SETTINGS, parameter=parameter)[1]) is not None:
            continue  # a (rare) false alarm of the control itself is not the outlier's doing
        for op in range(21, 61):
            history = fit_history(seed + 7000, nominal=nominal, outliers={op: rel})
            _, events = replay(history, SETTINGS, parameter=parameter)
            assert first_alarm(events) is None, f"seed {seed}: outlier at {op} raised an alarm"
            checked += 1
    assert checked >= 2 * 40


def test_an_outlier_in_the_baseline_is_screened_out():
    history = fit_history(3, nominal=DO_NOMINAL, outliers={7: -0.30})
    state, _ = replay(history[:20], SETTINGS, parameter="DO")
    assert state.baseline.excluded_ids == (7,)
    assert state.baseline.n == 19
    assert abs(state.baseline.mean / DO_NOMINAL - 1) < 0.01
    assert state.baseline.sd / DO_NOMINAL < 0.03


# --- hysteresis and lifecycle -----------------------------------------------------------------

def test_hysteresis_one_warning_while_the_statistic_hovers_around_the_threshold():
    state = flat_baseline()
    k, hw = SETTINGS.k, SETTINGS.h_warning
    climb = [-(k + hw / 3 + 1e-6)] * 3  # S = h_warning
    hover = [-(k - 0.6), -(k + 0.6)] * 15  # S alternates h_warning - 0.6, h_warning, ...
    state, events, trace = feed(state, climb + hover, 21)
    crossings = sum(1 for a, b in zip(trace, trace[1:]) if (a >= hw) != (b >= hw))
    assert crossings >= 20  # the series really does hover around the threshold
    assert [(e.kind, e.level) for e in events] == [("raised", "warning")]
    assert state.level == "warning"


def test_lifecycle_raised_escalated_acknowledged_cleared():
    state = flat_baseline()
    state, events, _ = feed(state, [-(SETTINGS.k + SETTINGS.h_warning / 3 + 1e-6)] * 3, 21)  # S = h_warning
    assert [(e.kind, e.level) for e in events] == [("raised", "warning")]
    episode = events[0].episode
    state, acks = acknowledge(state, by="operator-1", time=T0 + timedelta(days=2))
    assert [a.kind for a in acks] == ["acknowledged"] and state.acknowledged
    assert acknowledge(state, by="operator-1", time=T0 + timedelta(days=2))[1] == []  # idempotent

    state, events, _ = feed(state, [-(SETTINGS.k + 1.0)] * 2, 24)  # S = h_warning + 2 > h_alarm
    assert [(e.kind, e.level) for e in events] == [("escalated", "alarm")]
    assert not state.acknowledged  # an escalation needs a fresh acknowledgement
    state, acks = acknowledge(state, by="operator-2", time=T0 + timedelta(days=3))
    assert state.acknowledged_by == "operator-2" and acks[0].level == "alarm"

    # Back to normal: S falls by k per fit, then must stay below clear_level clear_count times.
    state, events, trace = feed(state, [0.0] * 12, 26)
    assert [(e.kind, e.level, e.episode) for e in events] == [("cleared", "alarm", episode)]
    cleared_at = events[0].operation_id - 26
    first_below = next(i for i, s in enumerate(trace) if s < SETTINGS.clear_level)
    assert cleared_at == first_below + SETTINGS.clear_count - 1
    assert state.level == "none" and health_status([state]) == "ok"
    with pytest.raises(ValueError, match="no active DO alarm"):
        acknowledge(state, by="operator-1", time=T0)


def test_alarm_evidence_names_baseline_estimate_statistic_and_operations():
    history = fit_history(11, nominal=DO_NOMINAL, slope=-0.01)
    _, events = replay(history, SETTINGS, parameter="DO")
    alarm = next(e for e in events if e.level == "alarm")
    ev = json.loads(json.dumps(alarm.to_dict(), allow_nan=False))["evidence"]
    base = ev["baseline"]["operation_ids"]
    assert ev["baseline"]["n"] == len(base) >= 19
    assert set(range(1, 21)) - set(ev["baseline"]["excluded_operation_ids"]) <= set(base)
    assert not ev["temperature_compensated"]
    assert ev["current"]["operation_id"] == alarm.operation_id
    lo, hi = ev["current"]["ci95"]
    assert lo < ev["current"]["value"] < hi < ev["baseline"]["mean"]
    assert ev["statistic"] >= SETTINGS.h_alarm and ev["drift_direction"] == "falling"
    ids = ev["operation_ids"]
    assert ids[-1] == alarm.operation_id and ids == list(range(ids[0], alarm.operation_id + 1))
    assert ids[0] > 20 and max(base) <= ids[0]  # at most the excursion's first fit was learnt


# --- baseline reset ---------------------------------------------------------------------------

def test_baseline_reset_after_maintenance_clears_and_learns_the_new_level():
    leak = fit_history(5, nominal=DO_NOMINAL, slope=-0.01, n_ops=45)
    state, events = replay(leak, SETTINGS, parameter="DO")
    assert state.level == "alarm"
    state, cleared = reset_baseline(state, by="admin", time=T0 + timedelta(days=50))
    assert [(e.kind, e.level) for e in cleared] == [("cleared", "alarm")]
    assert "baseline reset" in cleared[0].reason
    assert state.phase == "baseline" and state.statistic == 0 and health_status([state]) == "unknown"

    # After maintenance DO sits 8 % lower than before and stays there: the new normal.
    after = [FitObservation(o.operation_id + 100, o.time + timedelta(days=100), o.value * 0.92,
                            ci95=(o.ci95[0] * 0.92, o.ci95[1] * 0.92))
             for o in fit_history(6, nominal=DO_NOMINAL, n_ops=60)]
    state, events = replay(after, SETTINGS, parameter="DO", state=state)
    assert events == []
    assert state.baseline.mean == pytest.approx(DO_NOMINAL * 0.92, rel=0.01)
    assert state.baseline.operation_ids[:20] == tuple(range(101, 121))
    assert state.baseline.n > 20  # and it kept learning while quiet
    assert state.episode == 1  # the next alarm gets a new episode number


# --- state persistence and ordering -----------------------------------------------------------

def test_state_round_trips_through_json_and_the_replay_continues_identically():
    history = fit_history(9, nominal=BO_NOMINAL, slope=+0.01)
    state = DriftState.new("BO", SETTINGS)
    reference, ref_events = replay(history, SETTINGS, parameter="BO")
    events = []
    for i, o in enumerate(history):
        if i == 45:
            state, acks = acknowledge(state, by="op", time=o.time)
            events += acks
        text = json.dumps(state.to_dict(), allow_nan=False)
        restored = DriftState.from_dict(json.loads(text))
        assert restored == state
        state, new = update(restored, o, SETTINGS)
        events += new
    assert state.level == "alarm" and state.acknowledged
    assert [e.to_dict() for e in events if e.kind != "acknowledged"] == [e.to_dict() for e in ref_events]


def test_a_repeated_operation_counts_once_and_an_older_one_is_refused():
    state = flat_baseline()
    low = obs(21, DO_NOMINAL * 0.95)
    state, _ = update(state, low, SETTINGS)
    again, events = update(state, low, SETTINGS)
    assert again == state and events == []
    with pytest.raises(ValueError, match="older than the last one"):
        update(state, obs(3, DO_NOMINAL), SETTINGS)


# --- bad input --------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, message", [
    ({"value": float("nan")}, "fitted value must be finite"),
    ({"value": float("inf")}, "fitted value must be finite"),
    ({"value": "39.5x"}, "fitted value must be a number"),
    ({"ci95": (40.0, 39.0)}, "negative width"),
    ({"ci95": (39.0, float("nan"))}, "ci95 bound must be finite"),
    ({"stderr": -0.1}, "stderr must be >= 0"),
    ({"time": datetime(2024, 1, 1)}, "timezone-aware"),
])
def test_bad_observation_is_refused_with_a_clear_message(kwargs, message):
    args = {"operation_id": 1, "time": T0, "value": 39.5, **kwargs}
    with pytest.raises(ValueError, match=message):
        FitObservation(**args)


def test_unknown_parameter_is_refused():
    with pytest.raises(ValueError, match="'AO' is not watched"):
        DriftState.new("AO", SETTINGS)
    with pytest.raises(ValueError, match="'AO' is not watched"):
        update(DriftState(parameter="AO"), obs(1, 1.0), SETTINGS)


@pytest.mark.parametrize("section, message", [
    ({"clear_level": 5.0}, "clear_level < h_warning <= h_alarm"),
    ({"design_false_alarms_per_10k": 1.0}, "must not exceed design_false_warnings_per_10k"),
    ({"z_cap": 1.0}, "must exceed k"),
    ({"k": float("nan")}, "k: Input should be a finite number"),
    ({"baseline_n": 2}, "baseline_n: Input should be greater than or equal to 3"),
    ({"baseline_max": 10}, r"baseline_max \(10\) must be at least baseline_n"),
    ({"watched": {"DO": "down"}}, "watched.DO must be one of falling, rising, both, got 'down'"),
    ({"h_alarn": 5.0}, "unknown alarm setting h_alarn"),
    ({"h_warning": 3.0}, "unknown alarm setting h_warning"),  # derived, not set
    ({"temperature_slopes": {"DO": [0.0, -0.01]}}, "lowest <= highest"),
])
def test_bad_settings_are_refused(section, message):
    with pytest.raises(ValueError, match=message):
        DriftSettings.from_mapping(section)


def test_state_of_another_version_is_refused():
    data = DriftState.new("DO", SETTINGS).to_dict() | {"version": 99}
    with pytest.raises(ValueError, match="version 99"):
        DriftState.from_dict(data)


# --- helpers for the service ------------------------------------------------------------------

def test_observations_from_a_fit_result_dict_take_the_watched_parameters():
    fit = {"parameters": {"AO": 1.0, "BO": 4800.0, "DO": 39.4},
           "ci95": {"AO": [0.9, 1.1], "BO": [4750.0, 4850.0], "DO": [39.0, 39.8]}}
    got = observations_from_fit(fit, operation_id=7, time=T0, settings=SETTINGS)
    assert set(got) == {"DO", "BO"}
    assert got["DO"].value == 39.4 and got["DO"].se == pytest.approx(0.4 / 1.959963984540054)


def test_settings_round_trip_and_health_status():
    assert DriftSettings.from_mapping(SETTINGS.to_dict()) == SETTINGS
    warn = DriftState(parameter="BO", phase="monitoring", level="warning")
    ok = DriftState(parameter="DO", phase="monitoring")
    assert health_status([ok, warn]) == "warning"
    assert health_status([ok]) == "ok" and health_status([]) == "unknown"


def test_arl_markov_chain_matches_the_published_cusum_table_and_the_defaults_are_quiet():
    # Classic one-sided CUSUM, k = 0.5: ARL0 = 336 (h = 4) and 930 (h = 5); ARL(1 sigma) = 10.4.
    assert cusum_arl(0.0, k=0.5, h=4.0) == pytest.approx(336, rel=0.01)
    assert cusum_arl(0.0, k=0.5, h=5.0) == pytest.approx(930, rel=0.01)
    assert cusum_arl(1.0, k=0.5, h=5.0) == pytest.approx(10.4, rel=0.02)
    s = SETTINGS
    assert cusum_arl(0.0, k=s.k, h=s.h_alarm, z_cap=s.z_cap) > 1e6  # known-baseline ARL0 [fits]
    assert cusum_arl(3.0, k=s.k, h=s.h_alarm, z_cap=s.z_cap) < 5  # a 3-sigma step: < 5 fits
