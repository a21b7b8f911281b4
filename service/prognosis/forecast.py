"""The prognosis of one limited parameter of one breaker: operations and date to its limit.

Pure: the caller passes the drift detector's state (service.alarms), the breaker's good fits of
the parameter since the last baseline reset, and the limit from the breaker file. Method and
calibration: docs/prognosis.md.

- Values are temperature-compensated with the detector's learnt slope, to the baseline
  window's mean temperature, so the temperature of the last operation does not move the result.
- The basis: with an active drift alarm, the fits since the alarm's change point (where its
  CUSUM last left zero: the maximum-likelihood change point of a CUSUM, Page 1954, Hinkley
  1971); otherwise every fit since the last baseline reset.
- The degradation path is an average of candidates weighted by their one-step-ahead predictions
  over the later half of the basis (pseudo-BMA+, Yao et al. 2018): straight and accelerating
  curves with Bayesian updating (paths.py; Lu & Meeker 1993, Gebraeel et al. 2005), a Wiener
  process with drift and, for a one-sided limit, a gamma process, their diffusion estimated from
  the history (wiener.py; Si et al. 2012, van Noortwijk 2009), and a line since the last change
  of slope found on the history (changepoint.py; after Adams & MacKay 2007). With a temperature
  channel a second slope above the reference temperature lets the effect bend; the slow
  remainder (annual harmonics with a REML-bounded prior) is noise with or without one.
- The crossing's quantiles are whole operations (mixture.py). The dates carry the duty cycle:
  the renewal rate of the last year's gaps and a block bootstrap of them (dates.py).
- Beyond ``horizon_years`` (at that rate) a quantile is reported as None: "no crossing within
  N years", not a huge number; a 5 % quantile within the horizon is kept when the median is not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime, timedelta

import numpy as np

from service.alarms.observation import FitObservation
from service.alarms.state import DriftState
from service.breaker_limits import ParameterLimit
from service.prognosis.averaging import pseudo_bma_plus_weights
from service.prognosis.bocpd import fit_change_points
from service.prognosis.calibration import FORECAST_AHEAD, Calibration
from service.prognosis.calibration import levels as calibrated_levels
from service.prognosis.calibration import summary as calibration_summary
from service.prognosis.dates import date_quantiles, recent_gaps
from service.prognosis.dates import operation_rate as renewal_rate
from service.prognosis.mixture import Mixture
from service.prognosis.paths import (
    FLAT_PRECISION,
    SHAPES,
    fit_path,
    lfo_log_density,
    shape_column,
)
from service.prognosis.wiener import SLOWING_GRID, fit_stochastic, share_draws

MODEL = ("linear and power-law degradation paths (Gebraeel et al. 2005), a Wiener/gamma process with its "
         "diffusion from the history (Si et al. 2012; van Noortwijk 2009) and a line since the last change "
         "of slope (after Adams & MacKay 2007), averaged by their one-step-ahead predictions (pseudo-BMA+, "
         "Yao et al. 2018)")
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
# Fits before the change point that anchor the path's start (a drift from the healthy level):
# the baseline window's size, enough to fix that level to sd/sqrt(200).
PRE_FITS = 200


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
    forecast : the level's 5/50/95 % quantiles [unit] at ``ahead`` openings from now (compensated):
        what calibration.issue keeps to score the fits to come
    calibration : calibration.summary: the probabilities the 5 % and 95 % crossings were read at
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
    limits: list = field(default_factory=list)
    paths: dict = field(default_factory=dict)
    seasonal: bool = False
    low_frequency_sd: float | None = None
    change_before_crossing: float | None = None
    hazard_per_operation: float | None = None
    notes: list = field(default_factory=list)
    forecast: dict = field(default_factory=dict)
    calibration: dict = field(default_factory=dict)


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


def _days(history: Sequence[FitObservation]) -> np.ndarray:
    return np.array([(o.time - history[0].time).total_seconds() / 86400.0 for o in history])


def operation_rate(history: Sequence[FitObservation]) -> float | None:
    """Fitted openings per day [1/day]: one over the mean gap of the last year (the renewal rate,
    dates.py); None when the gaps span less than a day."""
    return renewal_rate(_days(history)) if history else None


def basis_start(state: DriftState, m: int) -> tuple[int, str]:
    """Index of the basis's first fit among the last ``m`` and its name."""
    if state.level != "none":
        run = state.run_length_falling if state.s_falling >= state.s_rising else state.run_length_rising
        return max(0, m - max(run, MIN_BASIS)), "change point"
    return 0, "baseline reset"


def prognose(state: DriftState, history: Sequence[FitObservation], limit: ParameterLimit, *,
             horizon_years: float = 10.0, calibration: Calibration | None = None) -> Prognosis:
    """The prognosis of ``state.parameter`` against ``limit``.

    history : the parameter's good fits since the last baseline reset, oldest first, the same
        the detector was fed (its last one is "now")
    horizon_years : beyond this, at the breaker's own rate, a crossing is reported as None [years]
    calibration : the breaker's own forecast scores (calibration.py): the crossing's 5 % and 95 %
        quantiles are read at its corrected probabilities; None: at 5 % and 95 %
    """
    name, text = state.parameter, limit.describe()
    if state.phase != "monitoring" or state.model is None:
        return Prognosis(name, None, None, text, status="no trend",
                         reason=f"learning the baseline ({len(state.collected)} fits so far)")
    model = state.model
    bounds = limit.bounds(model.centre)
    all_limits = [{"direction": d, "value": v} for d, v in bounds]
    history = list(history)
    start, basis = basis_start(state, len(history))
    if len(history) - start < MIN_BASIS:
        return Prognosis(name, bounds[0][1], bounds[0][0], text, baseline=model.centre, status="no trend",
                         limits=all_limits,
                         reason=f"{len(history) - start} fits since the {basis}; a trend needs {MIN_BASIS}")
    fit = fit_paths(state, history, start, monotone=len(bounds) == 1)
    mix = Mixture(fit.candidates, fit.weights)
    p_falling = mix.probability_falling()
    direction, bound = bounds[0] if len(bounds) == 1 else bounds[0 if p_falling >= 0.5 else 1]
    n_now = float(len(history) - 1)
    times_days = _days(history)
    rate = renewal_rate(times_days)
    horizon = rate * DAYS_PER_YEAR * horizon_years if rate else float(ENDURANCE_OPERATIONS)
    level_now = float(mix.level_quantiles(np.array([n_now]), (0.5,))[0][0])
    past = level_now < bound if direction == "falling" else level_now > bound
    common = dict(baseline=model.centre, current=level_now, basis=basis, basis_operations=fit.basis_operations,
                  rate_per_day=rate, horizon_operations=horizon, horizon_years=horizon_years if rate else None,
                  reference_temperature=model.t_mean, limits=all_limits,
                  paths=_weights_by_label(fit),
                  seasonal=fit.seasonal, low_frequency_sd=fit.low_frequency_sd)
    early, late = calibrated_levels(calibration, direction)
    ops = [mix.crossing_quantile(bound, direction, p, n_now=n_now, horizon=horizon) for p in (early, 0.5, late)]
    ahead_f = np.array(FORECAST_AHEAD, dtype=float)
    f_lo, f_med, f_hi = mix.level_quantiles(n_now + ahead_f, QUANTILES)
    r6 = lambda a: [round(float(v), 6) for v in a]
    common.update(forecast={"ahead": r6(ahead_f), "median": r6(f_med), "lo": r6(f_lo), "hi": r6(f_hi)},
                  calibration=calibration_summary(calibration, direction) if calibration is not None else {})
    common.update(change_words(fit, history, bound, direction, model.centre))
    ahead, cdf = mix.crossing_cdf(bound, direction, n_now=n_now, horizon=horizon)
    p_within = float(np.interp(horizon, ahead, cdf))
    years = f"{horizon_years:g} years" if rate else f"{ENDURANCE_OPERATIONS:,} operations"
    whole = [_whole(x) if x <= horizon else None for x in ops]
    last_time = history[-1].time
    dates: list = [None, None, None]
    if rate and whole[0] is not None:
        ahead, cdf = mix.crossing_cdf(bound, direction, n_now=n_now, horizon=horizon)
        days = date_quantiles(cdf, ahead, recent_gaps(times_days), (early, 0.5, late))
        dates = [last_time + timedelta(days=d) if (x is not None and math.isfinite(d)
                                                   and d <= DAYS_PER_YEAR * horizon_years) else None
                 for x, d in zip(whole, days)]
    # The averaged drift's 90 % interval holds zero: not a due date. Say so rather than a median.
    if not past and 0.05 < p_falling < 0.95:
        # A slope not credibly different from zero is not a due date: say so rather than a median.
        # The earliest crossing (5 %) still stands: a slope that may be zero may also be steep.
        return Prognosis(name, bound, direction, text, **common, probability_within_horizon=p_within,
                         operations_to_limit=Quantiles(whole[0], None, None) if whole[0] is not None else None,
                         date_to_limit=Quantiles(dates[0], None, None) if dates[0] is not None else None,
                         fan=fan(mix, fit, n_now, [ops[0], math.inf, math.inf], horizon), status="no trend",
                         reason=f"no trend: the slope's 90 % interval holds zero; not expected to reach "
                                f"its limit within {years} at this rate")
    # A median beyond the horizon keeps the earlier quantiles that lie within it (the 5 % one:
    # the earliest credible crossing); None only for what lies beyond.
    return Prognosis(
        name, bound, direction, text, **common,
        operations_to_limit=Quantiles(*whole) if whole[0] is not None else None,
        date_to_limit=Quantiles(*dates) if dates[0] is not None else None,
        probability_within_horizon=p_within, fan=fan(mix, fit, n_now, ops, horizon),
        status="crossed" if past else "ok",
        reason="the trend is past the limit now: service is due" if past else "")


# A level step is told in words when it is this many of its own sds: a normal run-to-run scatter
# reaches it with probability 6e-5 (as REJECT_Z).
STEP_Z = 4.0


def change_words(fit: PathsFit, history: list, bound: float, direction: str, centre: float) -> dict:
    """The change-point family's part of the answer: the chance of a change of pace before the
    crossing (its segments' simulated share, averaged with their weights), the learnt hazard, and
    a level step with no maintenance logged, in words (the history starts at the last logged
    event, so any step inside it was not logged)."""
    cp = fit.change
    out: dict = {"notes": []}
    if cp is None:
        return out
    out["hazard_per_operation"] = round(cp.hazard, 6)
    segs = [(c, w) for c, w in zip(fit.candidates, fit.weights) if getattr(c, "kind", "") in ("flat", "sloped")
            and w > 1e-3]
    total = sum(w for _, w in segs)
    if total > 0:
        out["change_before_crossing"] = round(sum(w * c.simulated(bound, direction)[2] for c, w in segs) / total, 3)
    if cp.step is not None and cp.step_sd and abs(cp.step) >= STEP_Z * cp.step_sd and cp.last_change is not None:
        i = int(fit_index(fit, cp.last_change))
        if 0 <= i < len(history):
            when = history[i].time.strftime("%Y-%m-%d")
            rel = cp.step / abs(centre) * 100.0  # of the baseline
            out["notes"].append(
                f"a level step of {rel:+.1f} % on {when} (operation {history[i].operation_id}) with no maintenance "
                f"logged: it is read as a real change of the mechanism and stays in the trend; if the sensor was "
                f"remounted or recalibrated, or the part serviced, log it and the prognosis restarts there")
    return out


def fit_index(fit: PathsFit, window_index: int) -> int:
    """The history index of the change-point window's fit ``window_index`` (the window is the
    kept fits of the basis plus the fits before it)."""
    return int(fit.window_n[window_index]) if fit.window_n is not None else window_index


def _whole(x: float) -> int:
    """A crossing quantile in whole operations: the first opening by which it has crossed."""
    return math.ceil(x - 1e-9) if x > 0 else 0


def _weights_by_label(fit) -> dict:
    return dict(fit.family_weights)


@dataclass(frozen=True)
class PathsFit:
    """The candidate paths of one basis and their weights.

    n, y : the basis's operation counts and compensated values kept (gross errors dropped)
    seasonal : the annual harmonics were fitted (no temperature, a year of history)
    low_frequency_sd : sd of the residual's slow component carried by the interval [unit], or None
    family_weights : each family's pseudo-BMA+ weight, by name
    change : the change-point family's summary (the learnt hazard, the last change's step), or None
    """

    candidates: list
    weights: np.ndarray
    n: np.ndarray
    y: np.ndarray
    basis_operations: int
    seasonal: bool
    low_frequency_sd: float | None
    family_weights: dict = field(default_factory=dict)
    change: object = None
    window_n: np.ndarray | None = None


def _day_of_year(times) -> np.ndarray:
    return np.array([t.timetuple().tm_yday - 1 + (t.hour + t.minute / 60.0) / 24.0 for t in times])


@dataclass
class Basis:
    """The window the candidates are drawn through, and its nuisance columns.

    n, y, w, dt : operation counts [operations], compensated values [unit], relative precisions
    [-], the temperature slope error's column [K]; in_basis : the fits since the basis's start
    (the others are the PRE_FITS before the change point); keep : the fits kept after the gross
    errors are dropped; d0, scale_ops : the drift's origin and the basis's length S [operations]
    """

    n: np.ndarray
    y: np.ndarray
    w: np.ndarray
    dt: np.ndarray
    in_basis: np.ndarray
    harmonics: list
    d0: float
    start: int
    scale_ops: float
    seasonal: bool
    common_var: float
    bend: np.ndarray
    bend_var: float
    sd: float
    dof: float
    centre: float
    harmonic_precision: float = 0.0
    keep: np.ndarray | None = None
    lf_sd: float | None = None

    @property
    def variants(self) -> tuple:
        return ("free", "anchored") if (~self.in_basis).any() else ("free",)

    @property
    def first_pred(self) -> int:
        """The first kept fit each candidate is scored on: MIN_BASIS into the basis."""
        return int(np.flatnonzero(self.in_basis[self.keep])[0]) + MIN_BASIS

    def design(self, k, variant, with_harmonics=True):
        """(design [m, p], prior precisions [p], in sigma^-2 units, 0 flat) of the curve of
        shape ``k`` and ``variant`` (paths.py)."""
        n, in_basis = self.n, self.in_basis
        cols = [np.ones_like(n), shape_column(n, self.d0, self.scale_ops, k) * in_basis]
        prec = [0.0, 0.0]
        if with_harmonics and self.harmonics and (self.seasonal or self.harmonic_precision > 0):
            cols += self.harmonics
            prec += [0.0 if self.seasonal else self.harmonic_precision] * 2
        if variant == "free" and (~in_basis).any():
            cols.append((~in_basis).astype(float))
            prec.append(0.0)
        if self.common_var > 0:
            cols.append(self.dt)
            prec.append(self.sd ** 2 / self.common_var)
        if self.bend_var > 0:
            cols.append(self.bend)
            prec.append(self.sd ** 2 / self.bend_var)
        return np.stack(cols, axis=1), np.array(prec)

    def fit(self, k, variant, sel, with_harmonics=True):
        x, prec = self.design(k, variant, with_harmonics)
        return fit_path(x[sel], self.y[sel], self.w[sel], prec, prior_sd=self.sd, prior_dof=self.dof, shape=k,
                        scale_ops=self.scale_ops, d0=self.d0)

    def shared(self) -> list:
        """Nuisances shared by the stochastic and change-point paths, on the kept fits: (column,
        prior variance in sigma^2 units, inf flat) of the harmonics and the temperature slope's
        error and bend."""
        keep, out = self.keep, []
        if self.harmonics and (self.seasonal or self.harmonic_precision > 0):
            out += [(h_[keep], math.inf if self.seasonal else 1.0 / self.harmonic_precision) for h_ in self.harmonics]
        if self.common_var > 0:
            out.append((self.dt[keep], self.common_var / self.sd ** 2))
        if self.bend_var > 0:
            out.append((self.bend[keep], self.bend_var / self.sd ** 2))
        return out


def make_basis(state: DriftState, history: list, start: int) -> Basis:
    """The window (the basis and up to PRE_FITS fits before it), its compensated values, its
    nuisance columns, and the gross errors dropped.

    Without a temperature channel and with a year of history since the reset, the annual cycle
    (cos, sin of the day of year, centred on the baseline window so that the level is the one at
    the baseline's season) is fitted beside the path. With less than a year, the residual's slow
    component bounds the cycle's size (REML) instead of being read as trend.
    """
    model = state.model
    y_all, w_all, dt_all = compensated(state, history)
    n_all = np.arange(len(history), dtype=float)
    span_days = (history[-1].time - history[0].time).total_seconds() / 86400.0
    seasonal = not model.compensated and span_days >= DAYS_PER_YEAR
    lo = 0 if seasonal else max(0, start - PRE_FITS)
    n, y, w, dt = n_all[lo:], y_all[lo:], w_all[lo:], dt_all[lo:]
    angle = 2.0 * np.pi * _day_of_year([o.time for o in history]) / DAYS_PER_YEAR
    ids = {w_[0] for w_ in state.window}
    ref = np.array([o.operation_id in ids for o in history]) if ids else np.arange(len(history)) < model.n
    if not ref.any():
        ref = np.arange(len(history)) < model.n
    harmonics = [(col - col[ref].mean())[lo:] for col in (np.cos(angle), np.sin(angle))]
    # Temperature's effect may bend (oil viscosity is convex in T; a heater holds the oil above a
    # floor): a second slope above the reference temperature, (T - T_ref)+ [K] scaled like dt,
    # with a N(0, slope^2) prior (a bend as large as the learnt slope itself).
    bend = np.maximum(dt, 0.0)
    b = Basis(n=n, y=y, w=w, dt=dt, in_basis=n >= start, harmonics=harmonics, d0=float(start) - 1.0, start=start,
              scale_ops=max(float(len(history) - start), 1.0), seasonal=seasonal,
              common_var=model.slope_var if model.compensated else 0.0, bend=bend,
              bend_var=(model.slope ** 2 + model.slope_var) if model.compensated and (bend > 0).any() else 0.0,
              sd=model.sd, dof=float(model.dof), centre=model.centre)
    keep = np.ones(len(n), dtype=bool)
    first = b.fit(1.0, "free", keep, seasonal)
    resid = y - b.design(1.0, "free", seasonal)[0] @ first.beta
    # Gross fit errors (about 1 % of fits, 5-30 % off) would pull a least-squares line: drop the
    # fits beyond REJECT_Z posterior sds and draw it again.
    keep = np.abs(resid) * np.sqrt(w) <= REJECT_Z * first.sd
    if (b.in_basis & keep).sum() < MIN_BASIS:
        keep = np.ones(len(n), dtype=bool)
    b.keep = keep
    if not seasonal and low_frequency(resid[keep]) is not None:
        # Each harmonic's coefficient gets a N(0, v) prior (a cycle of amplitude A has variance
        # A^2 / 2 = v), v by restricted maximum likelihood (Patterson & Thompson 1971), and the
        # level is marginalised over the part of the cycle the history cannot pin down.
        x, _ = b.design(1.0, "free", False)
        v = cycle_variance(x[keep], np.stack(harmonics, axis=1)[keep], y[keep], w[keep], model.sd ** 2)
        b.harmonic_precision, b.lf_sd = model.sd ** 2 / v, math.sqrt(v)
    return b


def curve_families(b: Basis) -> list:
    """The power-law curves (paths.py), free and anchored, each a family of one: [(name,
    [(candidate, 1.0)], one-step log densities)]."""
    out = []
    keep = b.keep
    for variant in b.variants:
        for k in SHAPES:
            c = b.fit(k, variant, keep)
            x, prec = b.design(k, variant)
            prec = np.where(prec > 0, prec, FLAT_PRECISION)
            lp = lfo_log_density(np.ascontiguousarray(x[keep]), b.y[keep], b.w[keep], prec, b.sd ** 2, b.dof,
                                 b.first_pred)
            out.append((f"{variant} power {k:g}", [(replace(c, variant=variant), 1.0)], lp))
    return out


def stochastic_families(b: Basis, *, monotone: bool) -> list:
    """The Wiener path with a wandering drift, and the slowing path on the clock n^k (wiener.py),
    each with a gamma twin for a one-sided limit sharing its weight equally."""
    keep, shared = b.keep, b.shared()
    nuis = np.stack([c_ for c_, _ in shared], axis=1) if shared else None
    var = [v_ for _, v_ in shared]
    kw = dict(start=float(b.start), scale_ops=b.scale_ops, prior_sd=b.sd, prior_dof=b.dof, first=b.first_pred)
    kinds = ("wiener", "gamma") if monotone else ("wiener",)
    out = []
    for name, fam in (("stochastic", fit_stochastic(b.n[keep], b.y[keep], b.w[keep], nuis, var, **kw)),
                      ("slowing", fit_stochastic(b.n[keep], b.y[keep], b.w[keep], nuis, var, **kw,
                                                 drift_grid=(0.0,), clock_powers=SLOWING_GRID))):
        members = [(replace(c_, kind=k_, variant=name, sim_draws=nd, _draws={}), wt / len(kinds))
                   for c_, wt, nd in zip(fam.components, fam.weights, share_draws(fam.weights / len(kinds)))
                   for k_ in kinds]
        out.append((name, members, fam.log_density))
    return out


def change_point_family(b: Basis):
    """The segments since the last change found on the history (bocpd.py), or None.

    The nuisances (the annual harmonics, the temperature slope's error and bend) are global, not
    a segment's: they are taken out first, at their values in the straight line's fit over the
    whole window (their posterior mean), so a segment never re-learns a season."""
    keep = b.keep
    x, prec = b.design(1.0, "free")
    line = b.fit(1.0, "free", keep)
    y = b.y[keep].copy()
    nuis_cols = [j for j in range(2, x.shape[1]) if not (b.variants == ("free", "anchored") and j == _level_before(b))]
    for j in nuis_cols:
        y -= line.beta[j] * x[keep][:, j]
    return fit_change_points(b.n[keep], y, b.w[keep], None, [], centre=b.centre, scale_ops=b.scale_ops,
                             prior_sd=b.sd, prior_dof=b.dof, first=b.first_pred, d0=b.d0)


def _level_before(b: Basis) -> int:
    """The column of the free curve's own level before the change point (a segment's business,
    not a nuisance)."""
    x, _ = b.design(1.0, "free")
    before = (~b.in_basis).astype(float)
    for j in range(2, x.shape[1]):
        if np.array_equal(x[:, j], before):
            return j
    return -1


def fit_paths(state: DriftState, history: list, start: int, *, monotone: bool = False) -> PathsFit:
    """Every candidate family through the basis (``history[start:]``), weighted by pseudo-BMA+
    of their one-step predictions: the curves (paths.py), the stochastic and slowing paths
    (wiener.py; gamma twins when ``monotone``), the change-point segments (bocpd.py)."""
    b = make_basis(state, history, start)
    families = curve_families(b) + stochastic_families(b, monotone=monotone)
    cp = change_point_family(b)
    if cp is not None:
        families.append(("change points", list(zip(cp.components, cp.weights)), cp.log_density))
    fw = pseudo_bma_plus_weights(scored_columns(np.array([lp for _, _, lp in families])))
    cands = [c_ for _, fam, _ in families for c_, _ in fam]
    weights = np.array([f_ * wt for f_, (_, fam, _) in zip(fw, families) for _, wt in fam])
    sel = b.keep & b.in_basis
    return PathsFit(cands, weights, b.n[sel], b.y[sel], int(sel.sum()), b.seasonal, b.lf_sd,
                    family_weights={name: round(float(f_), 4) for f_, (name, _, _) in zip(fw, families)}, change=cp,
                    window_n=b.n[b.keep])


def scored_columns(lp: np.ndarray) -> np.ndarray:
    """The one-step predictions every family makes (the columns finite for all): the weights are
    pseudo-BMA+ over the whole leave-future-out sequence (Buerkner et al. 2020), not a part chosen
    after the fact."""
    return lp[:, np.isfinite(lp).all(axis=0)]


def low_frequency(resid: np.ndarray) -> tuple[float, float, float] | None:
    """(variance [unit^2] and AR(1) coefficient per operation [-] of the residual's slow
    component, the residual's variance [unit^2]), from its autocovariances at lags 1 and 2
    (white noise plus an AR(1): gamma(h) = v phi^h for h >= 1); None when the lag-1
    autocorrelation is not significant at 5 % (one-sided, 1.645 / sqrt(m))."""
    m = len(resid)
    if m < 10:
        return None
    r = resid - resid.mean()
    g0 = float(r @ r) / m
    g1 = float(r[1:] @ r[:-1]) / m
    g2 = float(r[2:] @ r[:-2]) / m
    if g0 <= 0 or g1 / g0 <= 1.645 / math.sqrt(m):
        return None
    phi = min(max(g2 / g1, g1 / g0), 0.99) if g2 > 0 else g1 / g0
    return min(g1 / phi, g0), phi, g0


def cycle_variance(x: np.ndarray, h: np.ndarray, y: np.ndarray, w: np.ndarray, s2: float) -> float:
    """The REML estimate of v in y = X b + H c + e, c ~ N(0, v I), e ~ N(0, s2 / w), b flat
    [unit^2], on a log grid from (0.1 s)^2 to (30 s)^2: -2 log L_R(v) = S(v) + log|A(v)| +
    k log v, with A(v) = [X H]' W [X H] / s2 + diag(0, I / v) and S(v) the penalised weighted
    sum of squares at its minimum."""
    z = np.hstack([x, h])
    zw = z.T * (w / s2)
    a0, r0 = zw @ z, zw @ y
    kx, kh = x.shape[1], h.shape[1]
    best, best_v = math.inf, s2
    for v in s2 * np.geomspace(0.01, 900.0, 25):
        a = a0.copy()
        a[kx:, kx:] += np.eye(kh) / v
        try:
            beta = np.linalg.solve(a, r0)
        except np.linalg.LinAlgError:
            continue
        r = y - z @ beta
        pen = float((w * r * r).sum() / s2 + (beta[kx:] ** 2).sum() / v)
        val = pen + float(np.linalg.slogdet(a)[1]) + kh * math.log(v)
        if val < best:
            best, best_v = val, float(v)
    return best_v


def fan(mix: Mixture, fit: PathsFit, n_now: float, ops: list[float], horizon: float) -> dict:
    """The projected level's 5/50/95 % band from the basis's start to past the 95 % crossing
    (or the horizon), operation counts from the basis's first fit [operations]."""
    n = fit.n
    span = n_now - n[0] + 1.0
    # Past the 95 % crossing; without one (no trend, or beyond the horizon), as far ahead as the
    # basis is long (or to the earliest crossing): further out the band only shows the
    # curvature's uncertainty, not the data.
    ahead = ops[2] if math.isfinite(ops[2]) else (max(ops[0], span) if math.isfinite(ops[0]) else span)
    ahead = min(max(ahead * 1.1, 0.25 * span), horizon)
    grid = np.linspace(n[0], n_now + ahead, FAN_POINTS)
    p05, median, p95 = mix.level_quantiles(grid, QUANTILES)
    r = lambda a: [round(float(v), 6) for v in a]
    return {"operations": r(grid - n[0]), "median": r(median), "p05": r(p05),
            "p95": r(p95), "now": n_now - n[0],
            "observed": {"operations": r(n - n[0]), "value": r(fit.y)}}
