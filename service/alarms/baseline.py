"""A breaker's learnt baseline of one parameter: level, spread and temperature dependence.

Pure functions, no I/O. The baseline is a window of good fits ``(operation id, value,
temperature or None, stderr)``. From it ``fit_model`` builds the predictive distribution of the
next fit at its temperature T (docs/alarms.md):

    x = a + b (T - T_mean) + e,       e ~ N(0, s^2)
    predictive variance  V = s^2 (1 + 1/n) + var_b (T - T_mean)^2 + max(0, se^2 - mean se^2)

b is the Theil-Sen slope (scipy.stats.theilslopes) shrunk towards, and clipped to, the range
physics allows; var_b is its posterior variance (a uniform prior over that range, combined with
the data's own slope variance). With too little temperature span the data hardly narrows the
prior, so a fit far from the window's temperatures gets a wide band rather than a false alarm.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, Sequence

import numpy as np
from scipy import stats

# Theil-Sen's slope has ~1/0.91 the variance of least squares under normal errors (Sen 1968;
# Wilcox 2012, section 10.2): the data's slope variance is s^2 / Sxx times this.
THEIL_SEN_VARIANCE_FACTOR = 1.0 / 0.91
# The model uses temperature when at least this share of the window carries one.
TEMPERATURE_SHARE = 0.5
# Theil-Sen costs O(n^2): past 40 fits its slope is re-estimated only when the window has grown
# by a quarter since (its standard error changes by < 12 % in between).
SLOPE_REFIT_FROM, SLOPE_REFIT_GROWTH = 40, 1.25


@dataclass(frozen=True)
class Model:
    """Predictive model of the next fit of one parameter [unit of the parameter, K].

    n : fits in the window; dof : degrees of freedom of s (n - 1, or n - 2 with a slope)
    centre : a, the expected value at t_mean; slope : b [unit/K]; slope_var : var(b) [(unit/K)^2]
    t_mean, t_var : mean and variance of the window's temperatures [C, K^2]; None: not compensated
    t_span : max - min of the window's temperatures [K]
    sd : s, the run-to-run sd of the residuals (fit error included); se2_mean : mean se^2 of the window
    """

    n: int
    dof: int
    centre: float
    slope: float
    slope_var: float
    sd: float
    se2_mean: float
    t_mean: float | None = None
    t_var: float = 0.0
    t_span: float = 0.0
    t_min: float = 0.0
    t_max: float = 0.0
    ts_slope: float | None = None  # the raw Theil-Sen slope [unit/K] and the window size it had
    ts_n: int = 0

    @property
    def compensated(self) -> bool:
        return self.t_mean is not None

    def predict(self, temperature: float | None, se: float) -> tuple[float, float]:
        """(mean, variance) of a new fit with standard error ``se`` at ``temperature`` [C]."""
        var = self.sd ** 2 * (1.0 + 1.0 / self.n) + max(0.0, se ** 2 - self.se2_mean)
        if self.t_mean is None:
            return self.centre, var
        if temperature is None:  # temperature unknown: any the window has seen
            return self.centre, var + (self.slope ** 2 + self.slope_var) * self.t_var
        dt = temperature - self.t_mean
        return self.centre + self.slope * dt, var + self.slope_var * dt * dt

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "Model":
        return cls(**d)


def theil_sen_slope(x: np.ndarray, t: np.ndarray) -> float | None:
    """Theil-Sen slope of x on t: the median of the pairwise slopes (Sen 1968) [unit/K]; the same
    estimate as ``scipy.stats.theilslopes(x, t)[0]`` without its confidence interval, which the
    detector does not use and which costs most of scipy's time. None: t does not vary."""
    i, j = np.triu_indices(x.size, 1)
    dt = t[j] - t[i]
    ok = dt != 0
    if not ok.any():
        return None
    return float(np.median((x[j] - x[i])[ok] / dt[ok]))


def _temperatures(temps: Sequence[float | None]) -> np.ndarray | None:
    have = [t for t in temps if t is not None]
    if not have or len(have) < TEMPERATURE_SHARE * len(temps) or len(have) < 3:
        return None
    t_mean = float(np.mean(have))
    return np.array([t_mean if t is None else float(t) for t in temps])


def _slope(x: np.ndarray, t: np.ndarray, s2: float, rel_range: tuple[float, float],
           level: float, b_ts: float | None) -> tuple[float, float]:
    """Theil-Sen slope ``b_ts`` of x on t, combined with the physics range (uniform prior) [unit/K]."""
    lo, hi = sorted((rel_range[0] * level, rel_range[1] * level))
    prior_mean, prior_var = 0.5 * (lo + hi), (hi - lo) ** 2 / 12.0
    sxx = float(np.sum((t - t.mean()) ** 2))
    if prior_var == 0.0:
        return prior_mean, 0.0
    if sxx <= 0.0 or x.size < 3 or b_ts is None:
        return prior_mean, prior_var
    data_var = max(s2, 1e-300) * THEIL_SEN_VARIANCE_FACTOR / sxx
    post_var = 1.0 / (1.0 / prior_var + 1.0 / data_var)
    b = post_var * (prior_mean / prior_var + b_ts / data_var)
    return float(min(hi, max(lo, b))), float(post_var)


def fit_model(values: Sequence[float], temps: Sequence[float | None], ses: Sequence[float], *,
              slope_range: tuple[float, float] | None, sd_floor_rel: float,
              previous: Model | None = None) -> Model:
    """The predictive model of a baseline window (values [unit], temperatures [C], stderrs [unit]).

    ``previous``: the model of the same window one fit shorter; its Theil-Sen slope is reused
    while the window has grown by less than SLOPE_REFIT_GROWTH since it was estimated.
    """
    x = np.asarray(values, dtype=float)
    n = int(x.size)
    se2 = float(np.mean(np.square(np.asarray(ses, dtype=float)))) if n else 0.0
    t = _temperatures(temps) if slope_range is not None else None
    level = float(np.mean(x))
    floor = sd_floor_rel * max(abs(level), 1e-12)
    if t is None:
        sd = float(np.std(x, ddof=1)) if n > 1 else floor
        return Model(n=n, dof=max(n - 1, 1), centre=level, slope=0.0, slope_var=0.0,
                     sd=max(sd, floor), se2_mean=se2)
    ts, ts_n = None, 0
    if previous is not None and previous.ts_slope is not None and n >= SLOPE_REFIT_FROM \
            and n < SLOPE_REFIT_GROWTH * previous.ts_n:
        ts, ts_n = previous.ts_slope, previous.ts_n
    elif n >= 3 and np.ptp(t) > 0:
        ts, ts_n = theil_sen_slope(x, t), n
    # Two passes: the slope's weight needs the residual spread, which needs a slope.
    s2 = float(np.var(x, ddof=1)) if n > 1 else floor ** 2
    for _ in range(2):
        b, b_var = _slope(x, t, s2, slope_range, level, ts)
        r = x - b * (t - t.mean())
        s2 = max(float(np.var(r, ddof=2)) if n > 2 else s2, floor ** 2)
    return Model(n=n, dof=max(n - 2, 1), centre=float(np.mean(r)), slope=b, slope_var=b_var,
                 sd=math.sqrt(s2), se2_mean=se2, t_mean=float(t.mean()), t_var=float(t.var()),
                 t_span=float(t.max() - t.min()), t_min=float(t.min()), t_max=float(t.max()),
                 ts_slope=ts, ts_n=ts_n)


def screen(values: Sequence[float], temps: Sequence[float | None], *,
           slope_range: tuple[float, float] | None, screen_sigmas: float, screen_min_rel: float,
           sd_floor_rel: float) -> np.ndarray:
    """Keep-mask of the first baseline: a fit is a gross outlier, and is left out, when its
    (temperature-compensated) residual is further from the median than both ``screen_sigmas``
    MAD-sigmas and ``screen_min_rel`` of the median.

    The MAD of ~20 fits is itself noisy; when it comes out small, a pure MAD screen drops healthy
    fits and the sd collapses (false alarms), hence the second, relative, condition.
    """
    x = np.asarray(values, dtype=float)
    median = float(np.median(x))
    t = _temperatures(temps) if slope_range is not None else None
    r = x
    if t is not None and np.ptp(t) > 0:
        lo, hi = sorted((slope_range[0] * median, slope_range[1] * median))
        b = min(hi, max(lo, float(stats.theilslopes(x, t)[0])))
        r = x - b * (t - np.median(t))
    centre = float(np.median(r))
    mad_sd = max(float(stats.median_abs_deviation(r, scale="normal")), sd_floor_rel * max(abs(median), 1e-12))
    limit = max(screen_sigmas * mad_sd, screen_min_rel * abs(median))
    return np.abs(r - centre) <= limit
