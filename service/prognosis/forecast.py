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
from service.prognosis.changepoint import fit_change_point
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
from service.prognosis.wiener import fit_wiener

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
RECENT_MIN = 20
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
    ops = [mix.crossing_quantile(bound, direction, p, n_now=n_now, horizon=horizon) for p in QUANTILES]
    ahead, cdf = mix.crossing_cdf(bound, direction, n_now=n_now, horizon=horizon)
    p_within = float(np.interp(horizon, ahead, cdf))
    years = f"{horizon_years:g} years" if rate else f"{ENDURANCE_OPERATIONS:,} operations"
    whole = [_whole(x) if x <= horizon else None for x in ops]
    last_time = history[-1].time
    dates: list = [None, None, None]
    if rate and whole[0] is not None:
        ahead, cdf = mix.crossing_cdf(bound, direction, n_now=n_now, horizon=horizon)
        days = date_quantiles(cdf, ahead, recent_gaps(times_days), QUANTILES)
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


def _whole(x: float) -> int:
    """A crossing quantile in whole operations: the first opening by which it has crossed."""
    return math.ceil(x - 1e-9) if x > 0 else 0


def _label(c) -> str:
    if hasattr(c, "kind"):
        return f"{c.kind} process (diffusion ratio {c.ratio:g})"
    if c.variant == "since the last change":
        return "line since the last change of slope"
    return f"{c.variant} power {c.shape:g}"


def _weights_by_label(fit) -> dict:
    out: dict = {}
    for c, w in zip(fit.candidates, fit.weights):
        out[_label(c)] = out.get(_label(c), 0.0) + float(w)
    return {k: round(v, 4) for k, v in out.items()}


@dataclass(frozen=True)
class PathsFit:
    """The candidate paths of one basis and their stacking weights.

    n, y : the basis's operation counts and compensated values kept (gross errors dropped)
    seasonal : the annual harmonics were fitted (no temperature, a year of history)
    low_frequency_sd : sd of the residual's slow component carried by the interval [unit], or None
    """

    candidates: list
    weights: np.ndarray
    n: np.ndarray
    y: np.ndarray
    basis_operations: int
    seasonal: bool
    low_frequency_sd: float | None


def _day_of_year(times) -> np.ndarray:
    return np.array([t.timetuple().tm_yday - 1 + (t.hour + t.minute / 60.0) / 24.0 for t in times])


def fit_paths(state: DriftState, history: list, start: int, *, monotone: bool = False) -> PathsFit:
    """Fit every candidate path to the basis (``history[start:]``) and weight them by pseudo-BMA+.

    Families: the stochastic path (wiener.py; Wiener and, when ``monotone``, gamma sharing its
    weight), the line since the last change of slope (changepoint.py), and each power-law shape (paths.SHAPES), either continuing from the level before
    the change point ("anchored": a drift that starts from the healthy baseline, which fixes
    the path's start with the pre-change fits) or with a level of its own after it ("free": a
    step, then a drift). Without a temperature channel and with a year of history since the
    reset, the annual cycle (cos, sin of the day of year, centred on the baseline window so that
    the level is the one at the baseline's season) is fitted beside the path. With less than a
    year, the residual's slow component (an AR(1) from its autocorrelation) enters the errors'
    covariance and the level's variance instead of being read as trend.
    """
    model = state.model
    y_all, w_all, dt_all = compensated(state, history)
    n_all = np.arange(len(history), dtype=float)
    span_days = (history[-1].time - history[0].time).total_seconds() / 86400.0
    seasonal = not model.compensated and span_days >= DAYS_PER_YEAR
    lo = 0 if seasonal else max(0, start - PRE_FITS)
    n, y, w, dt = n_all[lo:], y_all[lo:], w_all[lo:], dt_all[lo:]
    harmonics, harmonic_precision = [], 0.0
    if True:  # the annual harmonics: fitted without temperature, a bound on the slow remainder with it
        angle = 2.0 * np.pi * _day_of_year([o.time for o in history]) / DAYS_PER_YEAR
        ids = {w_[0] for w_ in state.window}
        ref = np.array([o.operation_id in ids for o in history]) if ids else np.arange(len(history)) < model.n
        if not ref.any():
            ref = np.arange(len(history)) < model.n
        harmonics = [(col - col[ref].mean())[lo:] for col in (np.cos(angle), np.sin(angle))]
    common_var = model.slope_var if model.compensated else 0.0
    # Temperature's effect may bend (oil viscosity is convex in T; a heater holds the oil above a
    # floor): a second slope above the reference temperature, (T - T_ref)+ [K] scaled like dt,
    # with a N(0, slope^2) prior (a bend as large as the learnt slope itself). Two slopes meeting
    # at the reference temperature leave the level there, the one the limit refers to, unchanged.
    bend = np.maximum(dt, 0.0)
    bend_var = (model.slope ** 2 + model.slope_var) if model.compensated and (bend > 0).any() else 0.0
    d0 = float(start) - 1.0  # d = 1 at the basis's first fit
    scale_ops = max(float(len(history) - start), 1.0)
    in_basis = n >= start
    variants = ("free", "anchored") if (~in_basis).any() else ("free",)

    def design(k, variant, with_harmonics=True):
        cols = [np.ones_like(n), shape_column(n, d0, scale_ops, k) * in_basis]
        prec = [0.0, 0.0]
        if with_harmonics and harmonics and (seasonal or harmonic_precision > 0):
            cols += harmonics
            prec += [0.0 if seasonal else harmonic_precision] * 2
        if variant == "free" and (~in_basis).any():
            cols.append((~in_basis).astype(float))
            prec.append(0.0)
        if common_var > 0:
            cols.append(dt)
            prec.append(model.sd ** 2 / common_var)
        if bend_var > 0:
            cols.append(bend)
            prec.append(model.sd ** 2 / bend_var)
        return np.stack(cols, axis=1), np.array(prec)

    def fit(k, variant, sel, with_harmonics=True):
        x, prec = design(k, variant, with_harmonics)
        return fit_path(x[sel], y[sel], w[sel], prec, prior_sd=model.sd, prior_dof=model.dof, shape=k,
                        scale_ops=scale_ops, d0=d0)

    keep = np.ones(len(n), dtype=bool)
    first = fit(1.0, "free", keep, seasonal)
    resid = y - design(1.0, "free", seasonal)[0] @ first.beta
    # Gross fit errors (about 1 % of fits, 5-30 % off) would pull a least-squares line: drop the
    # fits beyond REJECT_Z posterior sds and draw it again.
    keep = np.abs(resid) * np.sqrt(w) <= REJECT_Z * first.sd
    if (in_basis & keep).sum() < MIN_BASIS:
        keep = np.ones(len(n), dtype=bool)
    lf_sd = None
    if not seasonal and low_frequency(resid[keep]) is not None:
        # Less than a year without temperature, and the residual's autocorrelation shows a slow
        # component: the annual cycle cannot be fitted, but its size can be bounded. Each
        # harmonic's coefficient gets a N(0, v) prior (a cycle of amplitude A has variance
        # A^2 / 2 = v), v by restricted maximum likelihood (Patterson & Thompson 1971), and the
        # level is marginalised over the part of the cycle the history cannot pin down.
        x, _ = design(1.0, "free", False)
        v = cycle_variance(x[keep], np.stack(harmonics, axis=1)[keep], y[keep], w[keep], model.sd ** 2)
        harmonic_precision, lf_sd = model.sd ** 2 / v, math.sqrt(v)
    cands, lps = [], []
    first_pred = int(np.flatnonzero(in_basis[keep])[0]) + MIN_BASIS
    for variant in variants:
        for k in SHAPES:
            if k < 1 and variant == "anchored":
                # A slowing path anchored at the healthy level is steepest at the change point:
                # it reads a late change point's drop as a slowing leak. Slowing paths are free.
                continue
            c = fit(k, variant, keep)
            cands.append(replace(c, variant=variant))
            x, prec = design(k, variant)
            prec = np.where(prec > 0, prec, FLAT_PRECISION)
            lps.append(lfo_log_density(np.ascontiguousarray(x[keep]), y[keep], w[keep], prec, model.sd ** 2,
                                       float(model.dof), first_pred))
    # Nuisances shared by the stochastic and change-point paths: (column, prior variance in
    # sigma^2 units, inf flat) of the harmonics, the temperature slope's error.
    shared = []
    if harmonics and (seasonal or harmonic_precision > 0):
        shared += [(h_[keep], math.inf if seasonal else 1.0 / harmonic_precision) for h_ in harmonics]
    if common_var > 0:
        shared.append((dt[keep], common_var / model.sd ** 2))
    if bend_var > 0:
        shared.append((bend[keep], bend_var / model.sd ** 2))
    # The stochastic paths (wiener.py): the level wanders everywhere (a step at the change point
    # too), the drift acts from the basis's start.
    nuis = shared
    wfit, wlp, _ = fit_wiener(n[keep], y[keep], w[keep], np.stack([c_ for c_, _ in nuis], axis=1) if nuis else None,
                              [v_ for _, v_ in nuis], start=float(start), scale_ops=scale_ops, prior_sd=model.sd,
                              prior_dof=float(model.dof), first=first_pred)
    kinds = ("wiener", "gamma") if monotone else ("wiener",)
    families = [[(c_, 1.0)] for c_ in cands] + [[(replace(wfit, kind=k_, _draws={}), 1.0 / len(kinds)) for k_ in kinds]]
    lps.append(wlp)
    # The path since the last change of slope found on the history (changepoint.py): a family of
    # lines, one per change point, weighted within it by the change point's posterior.
    cp = fit_change_point(n[keep], y[keep], w[keep], np.stack([c_ for c_, _ in shared], axis=1) if shared else None,
                          np.array([1.0 / v_ for _, v_ in shared]), d0=d0, scale_ops=scale_ops,
                          prior_sd=model.sd, prior_dof=float(model.dof), first=first_pred)
    if cp is not None:
        lps.append(cp[1])
        families.append([(replace(f_, variant="since the last change"), wt) for f_, wt in cp[0]])
    # Each family (a curve, the stochastic path, the change-point path) is weighted by its
    # predictions (pseudo-BMA+); within a family, by its own weights.
    fw = pseudo_bma_plus_weights(recent_columns(np.array(lps)))
    cands = [c_ for fam in families for c_, _ in fam]
    weights = np.array([f_ * wt for f_, fam in zip(fw, families) for _, wt in fam])
    sel = keep & in_basis
    return PathsFit(cands, weights, n[sel], y[sel], int(sel.sum()), seasonal, lf_sd)


def recent_columns(lp: np.ndarray) -> np.ndarray:
    """The later half of the columns every candidate predicts (at least RECENT_MIN of them): the
    weights ask which path predicts the breaker as it is now, so a path that fitted the early
    basis well but not what followed a change (a leak that stopped, a seal that tore) loses."""
    idx = np.flatnonzero(np.isfinite(lp).all(axis=0))
    if idx.size > 2 * RECENT_MIN:
        idx = idx[max(idx.size // 2, 0):]
    return lp[:, idx]


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
