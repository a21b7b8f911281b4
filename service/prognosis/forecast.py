"""The prognosis of one limited parameter of one breaker: operations and date to its limit.

Pure: the caller passes the drift detector's state (service.alarms), the breaker's good fits of
the parameter since the last baseline reset, and the limit from the breaker file. Method and
calibration: docs/prognosis.md.

- Values are temperature-compensated with the detector's learnt slope, to the baseline
  window's mean temperature, so the temperature of the last operation does not move the result.
- The basis: with an active drift alarm, the fits since the alarm's change point (where its
  CUSUM last left zero: the maximum-likelihood change point of a CUSUM, Page 1954, Hinkley
  1971); otherwise every fit since the last baseline reset.
- The degradation path is linear in operations with Bayesian updating (trend.py). The date
  follows from the breaker's own rate of fitted openings over the last year.
- Beyond ``horizon_years`` (at that rate) a quantile is reported as None: "no crossing within
  N years", not a huge number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Sequence

import numpy as np
from scipy import stats

from service.alarms.observation import FitObservation
from service.alarms.state import DriftState
from service.breaker_limits import ParameterLimit
from service.prognosis.trend import Trend, fit_trend

MODEL = "linear degradation path, Bayesian updating (Gebraeel et al. 2005)"
QUANTILES = (0.05, 0.5, 0.95)
# Fewest fits a trend is drawn through: with two free coefficients, three residual degrees of
# freedom of its own besides the baseline's prior.
MIN_BASIS = 5
# Without a known operation rate the horizon is the mechanical endurance of a class M2 breaker,
# 10 000 operations (IEC 62271-100, 3.4.111 and 6.101.2.4).
ENDURANCE_OPERATIONS = 10_000
DAYS_PER_YEAR = 365.25
# A fit further than this many sds from the trend is a gross error: a normal fit lies there with
# probability 6e-5, so a basis of 1 000 fits loses 0.06 good ones on average.
REJECT_Z = 4.0
FAN_POINTS = 41


@dataclass(frozen=True)
class Quantiles:
    """5 %, 50 % and 95 % quantiles; None: beyond the horizon."""

    p05: float | datetime | None
    median: float | datetime | None
    p95: float | datetime | None


@dataclass(frozen=True)
class Prognosis:
    """The prognosis of one parameter.

    limit : the bound it forecasts [unit]; direction : "falling" (lower limit) | "rising"
    limit_text : the limit as written in the breaker file
    baseline : the compensated baseline it is relative to [unit]
    current : the trend's level now [unit], compensated to ``reference_temperature`` [C]
    operations_to_limit : remaining operations [operations], or None beyond the horizon
    date_to_limit : datetimes, or None (no rate, or beyond the horizon)
    basis : "change point" | "baseline reset"; basis_operations : fits the trend was drawn through
    rate_per_day : fitted openings per day over the last year, or None
    horizon_operations, horizon_years : the horizon beyond which a crossing is "none"
    probability_within_horizon : P(crossing before the horizon) [-]
    fan : the projected level, {"operations": [...], "p05", "median", "p95"} (operation counts
        from the basis's first fit), and "observed" compensated values of the basis
    status : "ok" | "crossed" (the trend is past the limit now: service is due) | "no trend"
        (reason in ``reason``)
    """

    parameter: str
    limit: float | None
    direction: str | None
    limit_text: str
    baseline: float | None = None
    current: float | None = None
    operations_to_limit: Quantiles | None = None
    date_to_limit: Quantiles | None = None
    model: str = MODEL
    basis: str | None = None
    basis_operations: int = 0
    rate_per_day: float | None = None
    horizon_operations: float | None = None
    horizon_years: float | None = None
    probability_within_horizon: float | None = None
    reference_temperature: float | None = None
    fan: dict = field(default_factory=dict)
    status: str = "ok"
    reason: str = ""


def compensated(state: DriftState, history: Sequence[FitObservation]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(values compensated to the window's mean temperature [unit], relative weights [-],
    temperature offsets T - T_mean [K], 0 where unknown).

    The learnt slope's error is common to every fit: the trend carries it as a term of its own
    (trend.fit_trend's ``common``). A fit without a temperature in a compensated model keeps its
    value and gets the variance of the window's temperatures times the slope's second moment
    (as in the detector's band).
    """
    m = state.model
    s2 = m.sd ** 2
    values = np.array([o.value for o in history], dtype=float)
    extra = np.array([max(0.0, o.se ** 2 - m.se2_mean) for o in history], dtype=float)
    dt = np.zeros_like(values)
    if m.compensated:
        temps = np.array([np.nan if o.temperature is None else o.temperature for o in history], dtype=float)
        known = np.isfinite(temps)
        dt = np.where(known, temps - m.t_mean, 0.0)
        # Viscosity and stiffness scale the parameter: the learnt slope is relative to the
        # baseline, so a breaker that has lost 25 % of its DO has lost 25 % of its slope too.
        values = values / (1.0 + m.slope / m.centre * dt)
        extra = extra + np.where(known, 0.0, (m.slope ** 2 + m.slope_var) * m.t_var)
        dt = dt * values / m.centre  # the slope error's effect on each compensated value [K]
    return values, s2 / (s2 + extra), dt


def operation_rate(history: Sequence[FitObservation]) -> float | None:
    """Fitted openings per day over the last year of ``history`` [1/day]; None below a day."""
    if len(history) < 2:
        return None
    last = history[-1].time
    recent = [o.time for o in history if o.time >= last - timedelta(days=DAYS_PER_YEAR)]
    span_days = (last - recent[0]).total_seconds() / 86400.0
    return (len(recent) - 1) / span_days if span_days >= 1.0 and len(recent) >= 2 else None


def basis_start(state: DriftState, m: int) -> tuple[int, str]:
    """Index of the basis's first fit among the last ``m`` and its name."""
    if state.level != "none":
        run = state.run_length_falling if state.s_falling >= state.s_rising else state.run_length_rising
        return max(0, m - max(run, MIN_BASIS)), "change point"
    return 0, "baseline reset"


def prognose(state: DriftState, history: Sequence[FitObservation], limit: ParameterLimit, *,
             horizon_years: float = 10.0) -> Prognosis:
    """The prognosis of ``state.parameter`` against ``limit``.

    history : the parameter's good fits since the last baseline reset, oldest first, the same
        the detector was fed (its last one is "now")
    horizon_years : beyond this, at the breaker's own rate, a crossing is reported as None [years]
    """
    name, text = state.parameter, limit.describe()
    if state.phase != "monitoring" or state.model is None:
        return Prognosis(name, None, None, text, status="no trend",
                         reason=f"learning the baseline ({len(state.collected)} fits so far)")
    model = state.model
    bounds = limit.bounds(model.centre)
    history = list(history)
    start, basis = basis_start(state, len(history))
    chosen = history[start:]
    if len(chosen) < MIN_BASIS:
        return Prognosis(name, bounds[0][1], bounds[0][0], text, baseline=model.centre, status="no trend",
                         reason=f"{len(chosen)} fits since the {basis}; a trend needs {MIN_BASIS}")
    y_all, w_all, dt_all = compensated(state, history)
    n, y, w, dt = np.arange(start, len(history), dtype=float), y_all[start:], w_all[start:], dt_all[start:]

    def draw(n, y, w, dt):
        return fit_trend(n, y, w, prior_sd=model.sd, prior_dof=model.dof, common=dt, common_var=model.slope_var)

    trend = draw(n, y, w, dt)
    # Gross fit errors (about 1 % of fits, 5-30 % off) would pull a least-squares line: drop the
    # fits beyond REJECT_Z posterior sds and draw it again.
    keep = np.abs(y - trend.level(n)[0]) * np.sqrt(w) <= REJECT_Z * trend.sd
    if not keep.all() and keep.sum() >= MIN_BASIS:
        n, y, w, dt = n[keep], y[keep], w[keep], dt[keep]
        trend = draw(n, y, w, dt)
    direction, bound = bounds[0] if len(bounds) == 1 else bounds[0 if trend.b < 0 else 1]
    n_now = float(len(history) - 1)
    rate = operation_rate(history)
    horizon = rate * DAYS_PER_YEAR * horizon_years if rate else float(ENDURANCE_OPERATIONS)
    ops = [trend.crossing_quantile(bound, direction, p, n_now=n_now) - n_now for p in QUANTILES]
    within = [x if x <= horizon else None for x in ops]
    last_time = history[-1].time
    dates = [last_time + timedelta(days=x / rate) if (x is not None and rate) else None for x in within]
    p_within = float(trend.crossing_probability(bound, direction, n_now + horizon))
    level_now = float(trend.level(n_now)[0])
    past = level_now < bound if direction == "falling" else level_now > bound
    return Prognosis(
        name, bound, direction, text, baseline=model.centre, current=level_now,
        operations_to_limit=Quantiles(*within) if within[1] is not None else None,
        date_to_limit=Quantiles(*dates) if dates[1] is not None else None,
        basis=basis, basis_operations=len(n), rate_per_day=rate,
        horizon_operations=horizon, horizon_years=horizon_years if rate else None,
        probability_within_horizon=p_within,
        reference_temperature=model.t_mean, fan=fan(trend, n, y, n_now, ops, horizon),
        status="crossed" if past else "ok",
        reason=f"the trend is past the limit now ({level_now:.4g} against {bound:.4g}): service is due"
        if past else "")


def fan(trend: Trend, n: np.ndarray, y: np.ndarray, n_now: float, ops: list[float],
        horizon: float) -> dict:
    """The projected level's 5/50/95 % band from the basis's start to past the 95 % crossing
    (or the horizon), operation counts from the basis's first fit [operations]."""
    ahead = ops[2] if math.isfinite(ops[2]) else horizon
    ahead = min(max(ahead * 1.1, 0.25 * (n_now - n[0]) + 1.0), horizon)
    grid = np.linspace(n[0], n_now + ahead, FAN_POINTS)
    mean, scale = trend.level(grid)
    t95 = float(stats.t.ppf(0.95, trend.dof))
    r = lambda a: [round(float(v), 6) for v in a]  # noqa: E731
    return {"operations": r(grid - n[0]), "median": r(mean), "p05": r(mean - t95 * scale),
            "p95": r(mean + t95 * scale), "now": n_now - n[0],
            "observed": {"operations": r(n - n[0]), "value": r(y)}}
