"""Blind degradation histories for judging the prognosis on data its authors did not write.

Written without reading the prognosis code, its bench or its tests: only docs/prognosis.md
(inputs, outputs, truth rules), the seed paper (Yan et al. 2026, Electronics: DO = cb rb^2 / J2
is the buffer damping factor whose fall diagnoses a buffer oil leak; BO = (kO xO1 rO - TOf) / J2
is the opening spring/resistance factor) and public literature. Pure numpy, no I/O.

Each generator draws its parameters at random over plausible ranges and returns a
`BlindHistory`. Units: DO in s^-1 (healthy 30-45), BO in s^-2 (healthy 3000-5000), times in
seconds since the first operation, temperatures in deg C. `true_level` is the noise-free value at
`reference_temperature_c` (the mean temperature of the first min(200, onset) operations, the
window a detector learns its baseline over; 20.0, unused, without a temperature channel);
`observed = true_level + temperature_effect + noise (+ outliers, offsets)`. The truth is
`truth_crossing`: the first operation whose `true_level` is at or past
`baseline * (1 + limit_change)`.

Noise model (deliberately not the bench's): relative run-to-run sd 0.7-2.5 % (Gaussian unless
a shape says otherwise), 0.3-2 % gross outliers 5-40 % off of either sign, half of them with a
CI inflated 3-10x (a poor fit that knows it) and half silent; stated CI half-width 0.8-1.2 % of
the value with a 15 % log-normal jitter per fit.

References: Whitmore (1995) Lifetime Data Anal. 1:307; Si, Wang, Hu, Zhou & Pecht (2012) IEEE
Trans. Reliab. 61:50; van Noortwijk (2009) Reliab. Eng. Syst. Saf. 94:2; Lu & Meeker (1993)
Technometrics 35:161; Whitmore & Schenkelberg (1997) Lifetime Data Anal. 3:27 (time-scale
power law); Ng (2008) IEEE Trans. Reliab. 57:2 and Bae & Kvam (2004) Technometrics 46:460
(two-phase paths); Andrade (1930) / ASTM D341 (oil viscosity vs temperature); Box & Jenkins
AR(1); Lange, Little & Taylor (1989) JASA 84:881 (Student-t errors); Kijima (1989) Eur. J. Oper.
Res. 41:11 (imperfect repair).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

DAY = 86400.0
YEARS_10_DAYS = 3652.5
MAX_OPS = 1500


@dataclass(frozen=True)
class BlindHistory:
    """One breaker parameter's history of fits. See the module docstring for units."""

    shape: str
    parameter: str                  # "DO" (s^-1) or "BO" (s^-2)
    baseline: float                 # healthy value, parameter's unit
    limit_change: float             # relative maintenance limit, e.g. -0.25
    times_s: np.ndarray             # s since the first operation, increasing
    temperature_c: np.ndarray | None
    true_level: np.ndarray          # noise-free, at reference_temperature_c
    temperature_effect: np.ndarray  # additive, parameter's unit
    observed: np.ndarray            # what a fit reports
    fit_ci95_halfwidth: np.ndarray  # the fit's own 95 % CI half-width
    degrading: bool
    reference_temperature_c: float
    notes: str
    true_crosses_within_10y: bool | None = None  # healthy: true path crosses in 10 y at its duty
    sensor_offset: np.ndarray | None = None  # additive offset of the observed only (a remounted transducer)


def truth_crossing(h: BlindHistory) -> int | None:
    """Index of the first operation whose true_level is at or past the limit, None if never."""
    return _first_past(h.true_level, h.baseline * (1.0 + h.limit_change), h.limit_change)


def _first_past(level: np.ndarray, limit: float, limit_change: float) -> int | None:
    past = level <= limit if limit_change < 0 else level >= limit
    idx = np.flatnonzero(past)
    return int(idx[0]) if idx.size else None


def truth_idx(level: np.ndarray, base: float, lc: float) -> int:
    """_first_past for a relative limit, -1 when the path never crosses."""
    c = _first_past(level, base * (1 + lc), lc)
    return -1 if c is None else c


# ---------------------------------------------------------------- duty, temperature, noise
def _duty(rng: np.random.Generator, n: int, kind: str) -> np.ndarray:
    """Operation times [s]. regular: rate 0.5-2 /day with jitter; poisson: 0.3-3 /day;
    bursty: bursts of ~6-30 operations minutes-to-hours apart, then 1-6 weeks idle
    (autoreclose storms, test campaigns)."""
    if kind == "regular":
        gaps = rng.gamma(20.0, 1.0 / 20.0, n - 1) / rng.uniform(0.5, 2.0)
    elif kind == "poisson":
        gaps = rng.exponential(1.0 / rng.uniform(0.3, 3.0), n - 1)
    elif kind == "bursty":
        gaps_l: list[float] = []
        mean_burst, within = rng.uniform(6, 30), rng.uniform(0.01, 0.3)
        while len(gaps_l) < n - 1:
            gaps_l.append(rng.uniform(7.0, 42.0))
            gaps_l.extend(rng.exponential(within, rng.poisson(mean_burst)))
        gaps = np.asarray(gaps_l[: n - 1])
    else:
        raise ValueError(f"unknown duty kind {kind!r}")
    return np.concatenate([[0.0], np.cumsum(np.maximum(gaps, 1e-4) * DAY)])


def _seasonal_temperature(rng: np.random.Generator, times_s: np.ndarray) -> np.ndarray:
    """Ambient [deg C]: annual mean 0-18, half-swing 6-16, diurnal 2-6, weather sd 2-4;
    random start day of year (temperate climate, e.g. central Europe / north China)."""
    d = times_s / DAY + rng.uniform(0, 365.25)
    annual = rng.uniform(0, 18) - rng.uniform(6, 16) * np.cos(2 * np.pi * (d - 15) / 365.25)
    diurnal = rng.uniform(1, 3) * np.cos(2 * np.pi * (d % 1.0 - 0.625))
    return annual + diurnal + rng.normal(0, rng.uniform(2, 4), d.size)


def _oil_factor(rng: np.random.Generator, temp: np.ndarray, t_ref: float) -> tuple[np.ndarray, str]:
    """Multiplicative temperature factor of buffer damping, 1 at t_ref. Damping of an orifice
    buffer scales as viscosity^p, p 0.15-0.5 between turbulent (0) and laminar (1) flow; the
    viscosity follows Andrade, ln nu = A + B/T, B 2000-3500 K for mineral oil (ASTM D341 region):
    convex in T; p*B drawn 250-800 K (0.3-0.9 %/K at 20 deg C). Variants: 'andrade'; 'heater'
    (the cabinet's anti-condensation heater keeps the oil at or above 5-15 deg C: a kink, flat
    below it); 'quadratic' (a -0.3..-0.9 %/K slope with +0.5e-4..2.5e-4 /K^2 curvature)."""
    kind = ("andrade", "heater", "quadratic")[rng.integers(3)]
    if kind == "quadratic":
        a1, a2 = -rng.uniform(0.003, 0.009), rng.uniform(0.5e-4, 2.5e-4)
        f = lambda t: 1 + a1 * (t - t_ref) + a2 * (t - t_ref) ** 2
        return f(temp) / f(np.asarray(t_ref)), kind
    pb = rng.uniform(250, 800)  # p*B [K]
    if kind == "heater":
        rise, floor = rng.uniform(2, 8), rng.uniform(5, 15)
        oil = lambda t: np.maximum(t + rise, floor)
    else:
        oil = lambda t: t
    g = lambda t: np.exp(pb / (oil(t) + 273.15))
    return g(temp) / g(np.asarray(t_ref)), kind


def _noise(rng: np.random.Generator, n: int, kind: str, sd: float) -> np.ndarray:
    """Relative run-to-run noise: 'gauss'; 't' (Student t, 2.5-5 dof, scaled to sd);
    'ar1' (AR(1), phi 0.5-0.9, marginal sd)."""
    if kind == "gauss":
        return rng.normal(0, sd, n)
    if kind == "t":
        nu = rng.uniform(2.5, 5.0)
        return sd * rng.standard_t(nu, n) / np.sqrt(nu / (nu - 2))
    phi, e = rng.uniform(0.5, 0.9), np.empty(n)
    e[0] = rng.normal(0, sd)
    w = rng.normal(0, sd * np.sqrt(1 - phi**2), n)
    for i in range(1, n):
        e[i] = phi * e[i - 1] + w[i]
    return e


def _assemble(rng, shape, parameter, baseline, limit_change, times, temp, level, factor,
              degrading, n_ref, notes, noise="gauss", offset=None,
              crosses_10y=None) -> BlindHistory:
    """Add temperature effect, noise, outliers and the stated CI; cut nothing."""
    n = level.size
    effect = np.zeros(n) if factor is None else level * (factor - 1.0)
    clean = level + effect
    obs = clean * (1.0 + _noise(rng, n, noise, rng.uniform(0.007, 0.025)))
    ci = np.abs(obs) * rng.uniform(0.008, 0.012) * rng.lognormal(0.0, 0.15, n)
    out = rng.random(n) < rng.uniform(0.003, 0.02)
    out[:5] = False
    k = int(out.sum())
    obs[out] = clean[out] * (1.0 + rng.choice([-1.0, 1.0], k) * rng.uniform(0.05, 0.40, k))
    loud = out & (rng.random(n) < 0.5)
    ci[loud] *= rng.uniform(3, 10, int(loud.sum()))
    if offset is not None:
        obs = obs + offset
    t_ref = float(np.mean(temp[:n_ref])) if temp is not None else 20.0
    return BlindHistory(shape, parameter, float(baseline), float(limit_change), times, temp,
                        level, effect, obs, ci, degrading, t_ref, notes, crosses_10y,
                        np.zeros(n) if offset is None else np.asarray(offset, dtype=float))


def _cut(rng, level: np.ndarray, baseline: float, lc: float, min_tail: int = 15) -> int | None:
    """History length: the crossing plus a tail of 15-150 operations (<= MAX_OPS); None when the
    path does not cross within MAX_OPS - min_tail (the caller redraws)."""
    c = _first_past(level[:MAX_OPS], baseline * (1 + lc), lc)
    if c is None or c > MAX_OPS - min_tail:
        return None
    return int(min(MAX_OPS, c + rng.integers(min_tail, 151)))


def _redraw(draw: Callable[[], tuple | None]) -> tuple:
    """Rejection loop: draw until the path crosses within the history (bounded)."""
    for _ in range(200):
        got = draw()
        if got is not None:
            return got
    raise RuntimeError("no crossing drawn in 200 attempts")


def _temp_and_factor(rng, times, n_ref):
    temp = _seasonal_temperature(rng, times)
    factor, kind = _oil_factor(rng, temp, float(np.mean(temp[:n_ref])))
    return temp, factor, kind


# ---------------------------------------------------------------- degrading shapes
def wiener_drift(rng: np.random.Generator) -> BlindHistory:
    """DO leak as a Wiener process with drift (Whitmore 1995; Si et al. 2012): after an onset at
    operation 100-400, increments N(-mu, s^2) per operation; mean crossing 80-900 operations after
    the onset; the path's own spread at the mean crossing time is 10-50 % of the drop."""
    base, lc = rng.uniform(30, 45), -0.25
    def draw():
        n0, L, r = int(rng.integers(100, 401)), rng.uniform(80, 900), rng.uniform(0.1, 0.5)
        drop = -lc * base
        inc = rng.normal(-drop / L, r * drop / np.sqrt(L), MAX_OPS - n0)
        level = base + np.concatenate([np.zeros(n0), np.cumsum(inc)])
        end = _cut(rng, level, base, lc)
        return None if end is None else (level[:end], n0)
    level, n0 = _redraw(draw)
    times = _duty(rng, level.size, "regular")
    return _assemble(rng, "wiener_drift", "DO", base, lc, times, None, level, None, True,
                     min(200, n0), "Wiener with drift, diffusion 10-50% of drop at crossing "
                     "(Whitmore 1995; Si et al. 2012); no temperature channel")


def gamma_process(rng: np.random.Generator) -> BlindHistory:
    """BO spring relaxation as a stationary gamma process in calendar time (van Noortwijk 2009):
    Poisson duty 0.3-3 /day; after 100-400 operations, increments Gamma(alpha dt, beta), shape
    0.05-3 per mean operation gap (small: rare large jumps), mean crossing 80-900 ops later."""
    base, lc = rng.uniform(3000, 5000), -0.10
    def draw():
        times = _duty(rng, MAX_OPS, "poisson")
        days = times / DAY
        n0, L = int(rng.integers(100, 401)), rng.uniform(80, 900)
        rate = (MAX_OPS - 1) / days[-1]
        alpha = rng.uniform(0.05, 3.0) * rate                 # per day
        beta = (-lc * base) / (L / rate) / alpha
        jumps = rng.gamma(np.maximum(alpha * np.diff(days[n0 - 1:]), 1e-12), beta)
        level = base - np.concatenate([np.zeros(n0), np.cumsum(jumps)])
        end = _cut(rng, level, base, lc)
        return None if end is None else (level[:end], times[:end], n0)
    level, times, n0 = _redraw(draw)
    return _assemble(rng, "gamma_process", "BO", base, lc, times, None, level, None, True,
                     min(200, n0), "monotone gamma-process spring relaxation, jumpy when shape "
                     "is small (van Noortwijk 2009); Poisson duty; no temperature channel")


def slowing(rng: np.random.Generator) -> BlindHistory:
    """DO leak whose rate shrinks: half the draws a power law d^b, b 0.35-0.8 (Whitmore &
    Schenkelberg 1997 time scale; Lu & Meeker 1993), half an exponential approach A(1-e^-d/tau)
    to an asymptote 1.1-1.8x the limit's drop (a leak driven by the falling oil head). Crossing
    80-900 operations after an onset at 100-400."""
    base, lc = rng.uniform(30, 45), -0.25
    n0, L = int(rng.integers(100, 401)), rng.uniform(80, 900)
    d, drop = np.arange(MAX_OPS - n0) + 1.0, -lc * base
    if rng.random() < 0.5:
        b = rng.uniform(0.35, 0.8)
        loss, kind = drop * (d / L) ** b, f"power b={b:.2f}"
    else:
        amp = drop * rng.uniform(1.1, 1.8)
        tau = L / -np.log(1 - drop / amp)                   # crosses at d = L
        loss, kind = amp * (1 - np.exp(-d / tau)), "exponential approach"
    level = base - np.concatenate([np.zeros(n0), loss])
    level = level[: _cut(rng, level, base, lc)]
    times = _duty(rng, level.size, "regular")
    return _assemble(rng, "slowing", "DO", base, lc, times, None, level, None, True,
                     min(200, n0), f"decelerating leak ({kind}; Whitmore & Schenkelberg 1997)")


def slow_then_fast(rng: np.random.Generator) -> BlindHistory:
    """DO: a slow linear leak from an onset at 100-400 that has lost 10-50 % of the limit's drop
    when, 60-600 operations later, the slope grows 3-12x (a seal that tears; two-phase paths, Ng
    2008, Bae & Kvam 2004). The change lies >= 15 operations before the crossing."""
    base, lc = rng.uniform(30, 45), -0.25
    def draw():
        n0, c, f, m = int(rng.integers(100, 401)), int(rng.integers(60, 601)), \
            rng.uniform(0.1, 0.5), rng.uniform(3, 12)
        drop = -lc * base
        s1 = f * drop / c
        if (1 - f) * drop / (m * s1) < 15 or n0 + c + (1 - f) * drop / (m * s1) > MAX_OPS - 15:
            return None
        d = np.arange(MAX_OPS - n0) + 1.0
        loss = np.where(d <= c, s1 * d, s1 * c + m * s1 * (d - c))
        level = base - np.concatenate([np.zeros(n0), loss])
        end = _cut(rng, level, base, lc)
        return None if end is None else (level[:end], n0)
    level, n0 = _redraw(draw)
    times = _duty(rng, level.size, "regular")
    return _assemble(rng, "slow_then_fast", "DO", base, lc, times, None, level, None, True,
                     min(200, n0), "two-phase leak, slope x3-12 at a random change point "
                     "(Ng 2008; Bae & Kvam 2004)")


def leak_nonlinear_temperature(rng: np.random.Generator) -> BlindHistory:
    """DO linear leak in calendar time under seasonal temperature (one or more years) with a
    temperature effect that is not linear: Andrade viscosity, heater-kinked or quadratic
    (see _oil_factor). Onset at 100-250, crossing 300-1100 operations later, duty 0.5-2 /day."""
    base, lc = rng.uniform(30, 45), -0.25
    def draw():
        times = _duty(rng, MAX_OPS, "regular")
        days = times / DAY
        n0, L = int(rng.integers(100, 251)), rng.uniform(300, 1100)
        if n0 + L > MAX_OPS - 15:
            return None
        rate_day = (-lc * base) / (days[int(n0 + L)] - days[n0])
        level = base - rate_day * np.maximum(days - days[n0], 0.0)
        end = _cut(rng, level, base, lc)
        return None if end is None else (level[:end], times[:end], n0)
    level, times, n0 = _redraw(draw)
    temp, factor, kind = _temp_and_factor(rng, times, min(200, n0))
    return _assemble(rng, "leak_nonlinear_temperature", "DO", base, lc, times, temp, level,
                     factor, True, min(200, n0), f"seasonal leak, {kind} oil-viscosity "
                     "temperature effect (Andrade 1930; ASTM D341)")


def bursty_duty_leak(rng: np.random.Generator) -> BlindHistory:
    """DO leak at a constant rate per calendar day (a seal seeps whether or not the breaker
    operates) under a bursty duty: bursts of operations, then 1-6 weeks idle, so the level jumps
    across idle gaps and openings-to-limit differs from days-to-limit. Crossing 90-1000 days after
    an onset at operation 100-400."""
    base, lc = rng.uniform(30, 45), -0.25
    def draw():
        times = _duty(rng, MAX_OPS, "bursty")
        days = times / DAY
        n0 = int(rng.integers(100, 401))
        level = base + lc * base / rng.uniform(90, 1000) * np.maximum(days - days[n0], 0.0)
        end = _cut(rng, level, base, lc)
        return None if end is None else (level[:end], times[:end], n0)
    level, times, n0 = _redraw(draw)
    return _assemble(rng, "bursty_duty_leak", "DO", base, lc, times, None, level, None, True,
                     min(200, n0), "calendar-time leak under bursty duty (renewal/Poisson-cluster "
                     "arrivals, idle weeks); no temperature channel")


def heavy_tail_or_ar_noise(rng: np.random.Generator) -> BlindHistory:
    """DO linear leak (Lu & Meeker 1993) seen through Student-t (2.5-5 dof; Lange et al. 1989)
    or AR(1) (phi 0.5-0.9) run-to-run noise; Poisson duty; crossing 80-900 ops after 100-400."""
    base, lc = rng.uniform(30, 45), -0.25
    n0, L = int(rng.integers(100, 401)), rng.uniform(80, 900)
    d = np.arange(MAX_OPS - n0) + 1.0
    level = base - np.concatenate([np.zeros(n0), -lc * base * d / L])
    level = level[: _cut(rng, level, base, lc)]
    noise = ("t", "ar1")[rng.integers(2)]
    times = _duty(rng, level.size, "poisson")
    return _assemble(rng, "heavy_tail_or_ar_noise", "DO", base, lc, times, None, level, None,
                     True, min(200, n0), f"linear leak with {noise} run-to-run noise "
                     "(Lange et al. 1989; Box & Jenkins AR(1))", noise=noise)


def repair_relapse(rng: np.random.Generator) -> BlindHistory:
    """DO: a leak from an onset at 100-300 reaches 50-90 % of the limit's drop over 60-400
    operations, the buffer is refilled (level back to 0.97-1.04 x baseline, an imperfect repair,
    Kijima 1989), holds for 30-200 operations, then leaks again 1.5-4x faster. The truth refers
    to the original baseline; a prognosis made during the first leak is overtaken by the repair."""
    base, lc = rng.uniform(30, 45), -0.25
    def draw():
        n0, L1, f = int(rng.integers(100, 301)), int(rng.integers(60, 401)), rng.uniform(0.5, 0.9)
        hold, m, reset = int(rng.integers(30, 201)), rng.uniform(1.5, 4), rng.uniform(0.97, 1.04)
        s1 = f * -lc * base / L1
        first = base - s1 * np.arange(1, L1 + 1)
        tail = reset * base - m * s1 * np.arange(1, MAX_OPS)
        level = np.concatenate([np.full(n0, base), first, np.full(hold, reset * base), tail])
        level = level[:MAX_OPS]
        end = _cut(rng, level, base, lc)
        return None if end is None else (level[:end], n0)
    level, n0 = _redraw(draw)
    times = _duty(rng, level.size, "regular")
    return _assemble(rng, "repair_relapse", "DO", base, lc, times, None, level, None, True,
                     min(200, n0), "leak, imperfect refill, relapse faster (Kijima 1989); "
                     "truth vs the original baseline")


def recalibration_offset(rng: np.random.Generator) -> BlindHistory:
    """BO linear spring relaxation (0.01-0.1 % of baseline per op after an onset at 100-400) while
    the travel transducer is remounted once: from a random operation (after 150, >= 15 before the
    crossing) the fitted BO carries an offset of +-2-6 %; the true level is unaffected."""
    base, lc = rng.uniform(3000, 5000), -0.10
    def draw():
        n0, slope = int(rng.integers(100, 401)), rng.uniform(1e-4, 1e-3) * base
        level = base - slope * np.maximum(np.arange(MAX_OPS) - n0 + 1.0, 0.0)
        end = _cut(rng, level, base, lc)
        if end is None or truth_idx(level, base, lc) - 15 <= 150:
            return None
        return level[:end], n0
    level, n0 = _redraw(draw)
    at = int(rng.integers(150, truth_idx(level, base, lc) - 14))
    offset = np.where(np.arange(level.size) >= at,
                      base * rng.choice([-1.0, 1.0]) * rng.uniform(0.02, 0.06), 0.0)
    times = _duty(rng, level.size, "regular")
    temp = _seasonal_temperature(rng, times)
    factor = 1 - 3.6e-4 * (temp - np.mean(temp[: min(200, n0)]))  # steel modulus: -2.4e-4/K x 1.5
    return _assemble(rng, "recalibration_offset", "BO", base, lc, times, temp, level, factor, True,
                     min(200, n0), f"spring relaxation + sensor offset step at op {at} "
                     "(observed only); linear steel-modulus temperature effect", offset=offset)


def leak_that_stops(rng: np.random.Generator) -> BlindHistory:
    """DO: a leak from a seal above the oil's resting level stops once the level falls below
    the seal: linear for 60-600 operations after an onset at 100-400, then a plateau at 40-85 %
    of the limit's drop for 100-500 operations. Degrading, but NEVER crosses (truth None)."""
    base, lc = rng.uniform(30, 45), -0.25
    n0, L, f, plat = (int(rng.integers(100, 401)), int(rng.integers(60, 601)),
                      rng.uniform(0.4, 0.85), int(rng.integers(100, 501)))
    d = np.arange(min(L + plat, MAX_OPS - n0)) + 1.0
    level = base - np.concatenate([np.zeros(n0), f * -lc * base * np.minimum(d / L, 1.0)])
    times = _duty(rng, level.size, "regular")
    return _assemble(rng, "leak_that_stops", "DO", base, lc, times, None, level, None, True,
                     min(200, n0), "leak that stops at a plateau above the limit; never crosses")


# ---------------------------------------------------------------- healthy shapes
def healthy_wander(rng: np.random.Generator) -> BlindHistory:
    """DO or BO level wandering as AR(1) with memory 50-500 operations and stationary sd 0.5-4 %
    of the baseline (greasing, settling, seal swell). The true path is drawn out to 10 years at
    its duty to state whether it truly crosses there: DO's -25 % never in practice, BO's -10 %
    sometimes (2.5 sd at 4 %); such a history may then cross inside its own window too."""
    param = ("DO", "BO")[rng.integers(2)]
    base, lc = (rng.uniform(30, 45), -0.25) if param == "DO" else (rng.uniform(3000, 5000), -0.10)
    n = int(rng.integers(200, MAX_OPS + 1))
    times = _duty(rng, n, "regular")
    n10 = max(n, int(YEARS_10_DAYS * (n - 1) / (times[-1] / DAY)))
    phi, sd = 1 - 1 / rng.uniform(50, 500), rng.uniform(0.005, 0.04) * base
    w, x = rng.normal(0, sd * np.sqrt(1 - phi**2), n10), np.empty(n10)
    x[0] = rng.normal(0, sd)
    for i in range(1, n10):
        x[i] = phi * x[i - 1] + w[i]
    long = base + x
    crosses = _first_past(long, base * (1 + lc), lc) is not None
    return _assemble(rng, "healthy_wander", param, base, lc, times, None, long[:n], None, False,
                     200, f"healthy AR(1) wander; crosses within 10 y at its duty: {crosses}",
                     crosses_10y=crosses)


def healthy_seasonal(rng: np.random.Generator) -> BlindHistory:
    """Constant true level, seasonal temperature, nonlinear effect: DO with an oil factor
    (_oil_factor) or BO with grease friction rising 0.3-1 % of TOf per K below 0-10 deg C (a kink;
    TOf/J2 ~ half of BO) plus the steel modulus. Never truly crosses."""
    param = ("DO", "BO")[rng.integers(2)]
    n = int(rng.integers(300, MAX_OPS + 1))
    times = _duty(rng, n, "regular")
    if param == "DO":
        base, lc = rng.uniform(30, 45), -0.25
        temp, factor, kind = _temp_and_factor(rng, times, 200)
    else:
        base, lc, kind = rng.uniform(3000, 5000), -0.10, "grease kink"
        temp = _seasonal_temperature(rng, times)
        tk, q = rng.uniform(0, 10), rng.uniform(0.003, 0.01) * 0.5
        f = lambda t: 1 - 3.6e-4 * t - q * np.maximum(tk - t, 0)
        factor = f(temp) / f(np.mean(temp[:200]))
    return _assemble(rng, "healthy_seasonal", param, base, lc, times, temp, np.full(n, base),
                     factor, False, 200, f"healthy, {kind} temperature effect; never truly "
                     "crosses", crosses_10y=False)


def healthy_bursty(rng: np.random.Generator) -> BlindHistory:
    """Constant DO under a bursty duty (history cut at 4 years, >= 200 operations) with
    Student-t or AR(1) noise; never truly crosses."""
    base, times = rng.uniform(30, 45), _duty(rng, int(rng.integers(200, MAX_OPS + 1)), "bursty")
    n = max(200, int(np.searchsorted(times, 4 * 365.25 * DAY)))
    times, noise = times[:n], ("t", "ar1")[rng.integers(2)]
    return _assemble(rng, "healthy_bursty", "DO", base, -0.25, times, None, np.full(n, base),
                     None, False, 200, f"healthy, bursty duty, {noise} noise; never truly crosses",
                     noise=noise, crosses_10y=False)


SHAPES: dict[str, Callable[[np.random.Generator], BlindHistory]] = {
    f.__name__: f for f in (wiener_drift, gamma_process, slowing, slow_then_fast,
                            leak_nonlinear_temperature, bursty_duty_leak, heavy_tail_or_ar_noise,
                            repair_relapse, recalibration_offset, leak_that_stops,
                            healthy_wander, healthy_seasonal, healthy_bursty)
}
NEVER_CROSSES = frozenset({"leak_that_stops"})   # degrading, yet its truth is None by design


def main() -> None:
    for name, make in SHAPES.items():
        for seed in range(3):
            h = make(np.random.default_rng(seed))
            c = truth_crossing(h)
            print(f"{name:28s} seed {seed} {h.parameter} n={h.times_s.size:5d} "
                  f"days={h.times_s[-1] / DAY:7.1f} base={h.baseline:8.2f} cross={c} "
                  f"last obs/base={h.observed[-1] / h.baseline:.3f} | {h.notes}")
    for name in ("healthy_wander", "healthy_seasonal", "healthy_bursty"):
        share = np.mean([SHAPES[name](np.random.default_rng(1000 + s)).true_crosses_within_10y
                         for s in range(300)])
        print(f"{name}: true crossing within 10 years at its duty, share {share:.3f} (300 draws)")


if __name__ == "__main__":
    main()
