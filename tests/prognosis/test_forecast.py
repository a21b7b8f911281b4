"""The prognosis of one parameter from the detector's state (service.prognosis.forecast)."""

from __future__ import annotations

from dataclasses import replace
from datetime import datetime, timedelta, timezone

import numpy as np

from service.alarms import DriftSettings, DriftState, FitObservation, update
from service.breaker_limits import ParameterLimit
from service.prognosis import prognose

T0 = datetime(2025, 1, 1, tzinfo=timezone.utc)
LIMIT = ParameterLimit(min_change=-0.25)


def history(n: int, *, leak_from: int | None = None, rate: float = 0.01, seed: int = 1, temps=None):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        f = 1.0 - (rate * max(0, i - leak_from) if leak_from is not None else 0.0)
        t = None if temps is None else float(temps[i])
        tf = 1.0 if t is None else 1.0 - 0.004 * (t - 20.0)
        v = 39.5 * f * tf * (1 + 0.01 * rng.standard_normal())
        out.append(FitObservation(operation_id=i + 1, time=T0 + timedelta(days=i), value=v,
                                  ci95=(v - 0.4, v + 0.4), temperature=t))
    return out


def detector(obs):
    settings, state = DriftSettings(), DriftState.new("DO", DriftSettings())
    for o in obs:
        state, _ = update(state, o, settings)
    return state


def test_learning_baseline_gives_no_trend_with_reason():
    obs = history(10)
    p = prognose(detector(obs), obs, LIMIT)
    assert p.status == "no trend" and "learning the baseline" in p.reason and p.operations_to_limit is None


def test_healthy_breaker_says_no_trend_and_no_crossing_within_ten_years():
    """A flat history: the slope's 90 % interval holds zero, so "no trend", no median crossing."""
    obs = history(300)
    p = prognose(detector(obs), obs, LIMIT)
    assert p.status == "no trend" and "not expected to reach its limit within 10 years" in p.reason
    assert p.basis == "baseline reset"
    assert p.operations_to_limit is None or (p.operations_to_limit.median is None
                                             and p.operations_to_limit.p95 is None)
    assert p.date_to_limit is None or p.date_to_limit.median is None
    assert abs(p.rate_per_day - 1.0) < 1e-9
    assert p.horizon_operations == 3652.5 and p.probability_within_horizon < 0.5


def test_leak_gives_quantiles_around_the_truth_and_dates_from_the_rate():
    obs = history(120, leak_from=100)  # -1 %/op: 25 % down at op 126
    p = prognose(detector(obs), obs, LIMIT)
    q, d = p.operations_to_limit, p.date_to_limit
    assert p.basis == "change point" and q.p05 < q.median < q.p95
    assert q.p05 <= 126 - 120 <= q.p95
    assert d.median == obs[-1].time + timedelta(days=q.median)
    assert p.fan["median"][0] > p.fan["median"][-1]  # the projection falls


def test_a_limit_already_crossed_says_so():
    obs = history(150, leak_from=100)  # -1 %/op: past -25 % from op 126 on
    p = prognose(detector(obs), obs, LIMIT)
    assert p.status == "crossed" and "service is due" in p.reason and p.current < p.limit
    assert p.operations_to_limit.median == 0.0
    early = prognose(detector(obs[:120]), obs[:120], LIMIT)
    assert early.status == "ok" and early.reason == ""


def test_temperature_of_the_last_operation_does_not_move_the_prognosis():
    """Two breakers alike but for the last opening's temperature (and so its raw value): the
    compensated prognosis is the same to within the slope's own uncertainty."""
    rng = np.random.default_rng(7)
    temps = 5.0 + 15.0 * np.sin(np.arange(140) / 20.0) + rng.normal(0, 2, 140)
    obs = history(140, leak_from=120, temps=temps)
    state = detector(obs)
    base = prognose(state, obs, LIMIT)
    last = obs[-1]
    hot_t = last.temperature + 25.0
    hot_v = last.value * (1 - 0.004 * (hot_t - 20.0)) / (1 - 0.004 * (last.temperature - 20.0))
    hot = obs[:-1] + [replace(last, temperature=hot_t, value=hot_v, ci95=(hot_v - 0.4, hot_v + 0.4))]
    moved = prognose(state, hot, LIMIT)
    assert abs(moved.operations_to_limit.median - base.operations_to_limit.median) < 0.1 * base.operations_to_limit.median
    assert abs(moved.current - base.current) < 0.01 * base.current


def test_quantiles_are_whole_operations_and_the_5_percent_stays_within_the_horizon():
    # a slow leak whose median crossing lies beyond 10 years at one opening a week, its 5 % within
    rng = np.random.default_rng(8)
    t0 = datetime(2024, 1, 1, tzinfo=timezone.utc)
    n = 400
    true = 40.0 * (1 - 0.0003 * np.maximum(np.arange(n) - 100, 0))  # crosses 533 openings on
    obs = [FitObservation(operation_id=i + 1, time=t0 + timedelta(days=7 * i), value=float(v * (1 + 0.01 * rng.standard_normal())),
                          ci95=(float(v * 0.99), float(v * 1.01))) for i, v in enumerate(true)]
    settings = DriftSettings()
    state = DriftState.new("DO", settings)
    for o in obs:
        state, _ = update(state, o, settings)
    p = prognose(state, obs, ParameterLimit(min_change=-0.25))
    q = p.operations_to_limit
    assert q is not None and q.p05 is not None
    assert all(v is None or float(v).is_integer() for v in (q.p05, q.median, q.p95))
    assert q.p05 <= p.horizon_operations and q.median is None and q.p95 is None, q
    assert 0.05 <= p.probability_within_horizon < 0.5
    # the earliest crossing still stands, with its date
    assert p.date_to_limit is not None and p.date_to_limit.p05 is not None and p.date_to_limit.median is None


def _series(values):
    return [FitObservation(operation_id=i + 1, time=T0 + timedelta(days=i), value=float(v), ci95=(v - 0.4, v + 0.4),
                           temperature=None) for i, v in enumerate(values)]


def test_a_leak_that_stopped_is_not_given_a_due_date():
    """A leak of 0.5 %/op for 30 openings, then it holds at 15 % down for 150 (issue 50): the
    change points' flat segment and the drift's wander keep the 95 % quantile beyond the horizon."""
    rng = np.random.default_rng(21)
    d = np.arange(450, dtype=float)
    level = 39.5 * (1 - 0.005 * np.clip(d - 270, 0, 30))
    obs = _series(level * (1 + 0.01 * rng.standard_normal(d.size)))
    state = detector(obs)
    p = prognose(state, obs, LIMIT)
    q = p.operations_to_limit
    assert p.status in ("ok", "no trend") and (q is None or q.p95 is None), (p.status, q, p.paths)
    assert p.paths["change points"] > 0.2 and p.hazard_per_operation is not None


def test_an_unlogged_level_step_stays_a_step_and_is_said_in_words():
    """A 6 % step down at opening 300 with no maintenance logged: the trend keeps it, and the
    answer says the step was not logged and how to log it."""
    from service.jobs.prognosis import as_json

    rng = np.random.default_rng(22)
    d = np.arange(400, dtype=float)
    level = 39.5 * np.where(d >= 300, 0.94, 1.0)
    obs = _series(level * (1 + 0.01 * rng.standard_normal(d.size)))
    state = detector(obs)
    p = prognose(state, obs, LIMIT)
    note = next(n for n in p.notes if "level step" in n)
    size = float(note.split("level step of ")[1].split(" %")[0])
    assert "no maintenance logged" in note and abs(size - (-6.0)) <= 1.5, note  # 2 sd of two 20-fit lines
    assert "operation 30" in note and "log it and the prognosis restarts there" in note
    assert "Note: a level step" in as_json(p)["summary"]
    # logged: the history the prognosis reads starts at the entry, and the step is gone from it
    state2 = DriftState.new("DO", DriftSettings())
    for o in obs[300:]:
        state2, _ = update(state2, o, DriftSettings())
    assert not any("level step" in n for n in prognose(state2, obs[300:], LIMIT).notes)
