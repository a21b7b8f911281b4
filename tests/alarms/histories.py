"""Synthetic fit histories with a realistic noise model, shared by the tests and by
simulate_rates.py (which produces the rates quoted in docs/alarms.md).

A fit of operation i is  x_i = p * (1 + r_i) * (1 + sd_run * e_i) + se_i * f_i,
with e_i, f_i ~ N(0, 1): run-to-run spread sd_run (drawn per history in [1 %, 2 %]) and a fit
error consistent with the fit's own 95 % CI half-width (drawn per fit in [0.8 %, 1.2 %] of p).
r_i = slope * max(0, i - drift_from) is the drift: -1 %/op from operation 30 in the acceptance.
"""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np

from service.alarms import FitObservation

DO_NOMINAL = 39.5     # buffer damping coefficient [s^-1]
BO_NOMINAL = 4806.0   # opening-spring term [s^-2]
T0 = datetime(2024, 1, 1, tzinfo=timezone.utc)
Z95 = 1.959963984540054


def fit_history(seed: int, *, nominal: float, n_ops: int = 60, slope: float = 0.0,
                drift_from: int = 30, sd_range=(0.01, 0.02), ci_half_range=(0.008, 0.012),
                outliers: dict[int, float] | None = None) -> list[FitObservation]:
    """Observations of operations 1..n_ops (operation id = index, one operation a day).

    slope : relative drift per operation after ``drift_from`` [1/op], e.g. -0.01
    outliers : {operation: relative error} applied on top, e.g. {45: -0.30}
    """
    rng = np.random.default_rng(seed)
    sd_run = rng.uniform(*sd_range)
    i = np.arange(1, n_ops + 1)
    factor = 1.0 + slope * np.maximum(0, i - drift_from)
    half = rng.uniform(*ci_half_range, n_ops) * nominal  # 95 % CI half-width [unit]
    se = half / Z95
    x = nominal * factor * (1.0 + sd_run * rng.standard_normal(n_ops)) + se * rng.standard_normal(n_ops)
    for op, rel in (outliers or {}).items():
        x[op - 1] *= 1.0 + rel
    return [FitObservation(operation_id=int(op), time=T0 + timedelta(days=int(op)), value=float(v),
                           ci95=(float(v - h), float(v + h)))
            for op, v, h in zip(i, x, half)]


def first_alarm(events, level: str = "alarm") -> int | None:
    """Operation id at which ``level`` was first reached (raised or escalated), or None."""
    for e in events:
        if e.kind in ("raised", "escalated") and e.level == level:
            return e.operation_id
    return None


def seasonal_temperature(n_ops: int, *, day0: float = 0.0, seed: int = 0) -> np.ndarray:
    """Ambient temperature of operations 1..n_ops, one a day [C]: -25..+40 C over a year
    (coldest about 20 January), a daily swing of +-6 K and 2 K of weather (bench/alarm_rates.py)."""
    rng = np.random.default_rng(seed + 12345)
    day = day0 + np.arange(1, n_ops + 1)
    hour = rng.uniform(0, 24, n_ops)
    season = 7.5 - 32.5 * np.cos(2 * np.pi * (day - 20) / 365.25)
    return np.clip(season + 6.0 * np.sin(2 * np.pi * (hour - 9) / 24) + rng.normal(0, 2.0, n_ops), -25, 40)


def seasonal_history(seed: int, *, nominal: float, rel_per_k: float, n_ops: int = 500,
                     give_temperature: bool = True, slope: float = 0.0,
                     drift_from: int = 10**9) -> list[FitObservation]:
    """``fit_history`` with a temperature dependence x ~ (1 + rel_per_k (T - 20 C)); the
    temperature goes to the detector only when ``give_temperature``."""
    temps = seasonal_temperature(n_ops, day0=(seed * 37) % 365, seed=seed)
    base = fit_history(seed, nominal=nominal, n_ops=n_ops, slope=slope, drift_from=drift_from)
    out = []
    for o, t in zip(base, temps):
        f = 1.0 + rel_per_k * (t - 20.0)
        out.append(FitObservation(operation_id=o.operation_id, time=o.time, value=o.value * f,
                                  ci95=(o.ci95[0] * f, o.ci95[1] * f),
                                  temperature=float(t) if give_temperature else None))
    return out
