"""Stochastic degradation paths: a Wiener process whose drift is itself a filtered state with its
own random walk, a gamma process for one-sided wear, and a slowing path on a transformed time
scale. Their wander is estimated from the history itself.

Pure, numpy/numba/scipy only. The compensated value after operation n is

    y_i = L(n_i) + sum_j h_j s_j(i) + c x_i + e_i,       e_i ~ N(0, sigma^2 / w_i)
    L(n) = L(n') + int_{n'}^{n} b(s) dPhi(s) + W(n) - W(n'),      var W = r sigma^2 per op
    b(n) = b(n') + V(n) - V(n'),                                   var V = rho sigma^2 / S per op

(Whitmore 1995; Si, Wang, Hu & Zhou 2012 for the Wiener path with measurement error; Si, Wang,
Hu, Chen & Zhou 2013, MSSP 35, 219-237, for the drift as a hidden state updated by a Kalman
filter with its own process noise). Phi(n) = ((n - d0) / S)^k for n past the basis's start
(d0 = start - 1, S the basis's length), 0 before: k = 1 is operations themselves; k < 1 is the
time-scale transform Lambda(n) = n^k of a path that slows (Si et al. 2012, Whitmore &
Schenkelberg 1997). The drift acts from the basis's first fit on; the wandering W everywhere, so
a level that wanders (greasing, settling, seal swell) is noise, not trend. s_j and c x are the
nuisance columns (a level of its own before the change point, the annual harmonics, the
temperature slope's error), constant states of the filter.

The Kalman filter (one pass, O(m p^2)) gives the state at the last fit and every fit's one-step
predictive density given the fits before it; with sigma^2 conjugate (the baseline's
scaled-inverse-chi^2 prior) these are Student t. The wander ratios (r, rho) and the slowing
exponent k are not chosen but averaged: each point of their grid gets the posterior weight of
its prequential likelihood (Dawid 1984) under a uniform prior on the grid, and the family's
one-step density of fit i is the mixture over the grid weighted by the posterior given the fits
before i. The forecast carries what the filter says now *and* the wander still to come: the
drift's future random walk widens the crossing both ways (a leak may stop or speed up), which a
drift frozen at its filtered value (Si et al. 2013's forecast) does not.

Crossing (passage.py): with a drift that does not wander and k = 1, the inverse Gaussian first
passage averaged over stratified draws of (L, b, sigma); otherwise a seeded simulation of the
state forward. For a parameter whose limit has one side the gamma process with the same mean and
variance per operation (van Noortwijk 2009) shares the filter and its weight equally: its
one-step densities are the filter's, so no history can tell it from the Wiener path, only their
first passages differ (the 50/50 split is the uniform prior over two models the data cannot
rank).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy import special

from service.prognosis.passage import first_passage, simulate_passage

# Level-wander ratios r = var(W per operation) / sigma^2: a level that wanders by one run-to-run
# sd in 10 000 operations is r = 1e-4, by one sd per operation r = 1; half-decades between.
DIFFUSION_GRID = (0.0, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0)
# Drift-wander ratios rho = var(drift change over one basis length) / sigma^2 (drift in units per
# basis length): 0 a constant drift; 4 a drift that moves by 2 sd per basis length, up to 2048
# (45 sd: a leak that stops or doubles within the basis). Factors of 8: the prequential
# likelihood of a few hundred fits resolves a factor of a few in a variance, not finer.
DRIFT_WANDER_GRID = (0.0, 4.0, 32.0, 256.0, 2048.0)
# Slowing exponents k of Lambda(n) = n^k: the concave range (0, 1) in quarters.
SLOWING_GRID = (0.25, 0.5, 0.75)
DRAWS = 128  # stratified (Latin hypercube) draws for the closed form
# Simulated paths per family, shared among its members in proportion to their weights (at least
# MIN_SIM_DRAWS each): the Monte Carlo sd of a crossing probability of 5 % is then 0.007.
SIM_DRAWS = 1000
MIN_SIM_DRAWS = 64
SEED = 2012
DIFFUSE = 1e8  # prior variance of the level and drift [sigma^2 units]: flat in practice
# Grid points below this posterior weight are dropped from the forecast (and the rest
# renormalised): they move no quantile the answer shows.
MIN_WEIGHT = 1e-3
MAX_COMPONENTS = 4


@njit(cache=True)
def kalman(y, w, h, dn, gate, prior_var, r, qb, prior_sd2, prior_dof, first):
    """One pass of the Kalman filter of the model above, every variance in units of sigma^2.

    y [m], w [m] : values [unit] and relative precisions [-]; h [m, p] : observation rows (column
    0 the level, column 1 zero: the drift enters the transition, the rest nuisances, constant
    states); dn [m] : step of the drift's clock Phi to each fit [-] (0 for the first); gate [m] :
    the share of that step at or after the drift's start [-]; prior_var [p] : initial variances;
    r [m] : the level's wander over each step; qb [m] : the drift's random-walk variance over
    each step; prior_sd2, prior_dof : sigma^2's scaled-inverse-chi^2 prior; first : first fit
    whose density is scored. Returns (log predictive densities [m], -inf before ``first``; state
    mean [p]; its scale matrix [p, p]; the innovations' weighted sum of squares; the dof).
    """
    m, p = h.shape
    out = np.full(m, -np.inf)
    x = np.zeros(p)
    pm = np.zeros((p, p))
    for j in range(p):
        pm[j, j] = prior_var[j]
    ssr = 0.0
    n_eff = 0.0
    for i in range(m):
        if i > 0:
            d = dn[i] * gate[i]
            if d != 0.0:  # L += b d
                x[0] += x[1] * d
                col = pm[:, 1].copy()
                pm[:, 0] += d * col
                row = pm[1, :].copy()
                pm[0, :] += d * row
            if qb[i] > 0.0 and gate[i] > 0.0:  # the drift's random walk, integrated into L
                q = qb[i] * gate[i]
                pm[1, 1] += q
                pm[0, 1] += 0.5 * q * d
                pm[1, 0] += 0.5 * q * d
                pm[0, 0] += q * d * d / 3.0
            pm[0, 0] += r[i]
        hi = h[i]
        ph = pm @ hi
        f = 1.0 / w[i] + hi @ ph
        e = y[i] - hi @ x
        dof = prior_dof + n_eff - 2.0
        if i >= first and dof > 0:
            v = (prior_dof * prior_sd2 + ssr) / dof * f
            out[i] = (math.lgamma(0.5 * (dof + 1.0)) - math.lgamma(0.5 * dof)
                      - 0.5 * math.log(dof * math.pi * v) - 0.5 * (dof + 1.0) * math.log1p(e * e / v / dof))
        k = ph / f
        x = x + k * e
        pm = pm - np.outer(k, ph)
        pm = 0.5 * (pm + pm.T)
        ssr += e * e / f
        n_eff += 1.0
    return out, x, pm, ssr, prior_dof + n_eff - 2.0


def clock_of(n, d0: float, scale_ops: float, k: float):
    """The drift's clock past d0, 0 before [-]: (n - d0) / S for k = 1; for a slowing path
    (k < 1) the shifted power (1 + (n - d0) / S)^k - 1, whose rate is finite at the basis's start
    and falls by the factor 2^(k - 1) from there to one basis length on (a plain power's rate is
    infinite at the start: it would read the first few fits after the change point as the path)."""
    x = np.maximum(np.asarray(n, dtype=float) - d0, 0.0) / scale_ops
    return x if k == 1.0 else (1.0 + x) ** k - 1.0


@dataclass(frozen=True)
class WienerFit:
    """Posterior of one stochastic path at the last fit.

    beta : [L now, b now] posterior mean [unit, unit per unit of the clock Phi]; cov : their scale
    matrix (Student t with ``dof``) [unit^2]; sd : posterior sigma [unit]; diffusion : r sigma^2
    per operation [unit^2]; drift_wander : rho sigma^2 / S, the drift's variance per operation
    [(unit per clock unit)^2]; clock_power : k of Phi; scale_ops : S; d0 : Phi's origin; n_now :
    the last fit's operation count; kind : "wiener" | "gamma"
    """

    beta: np.ndarray
    cov: np.ndarray
    dof: float
    sd: float
    diffusion: float
    ratio: float
    scale_ops: float
    n_now: float
    drift_wander: float = 0.0
    drift_ratio: float = 0.0
    clock_power: float = 1.0
    d0: float = 0.0
    kind: str = "wiener"
    variant: str = "stochastic"
    shape: float = 1.0
    sim_draws: int = SIM_DRAWS
    _draws: dict = field(default_factory=dict, compare=False, repr=False)

    def clock(self, n):
        return clock_of(n, self.d0, self.scale_ops, self.clock_power)

    def level(self, n):
        """(mean, scale) of the level after operation ``n`` [unit] (Student t with ``dof``);
        ahead of now its scale carries the level's and the drift's wander still to come."""
        n = np.asarray(n, dtype=float)
        t = np.maximum(n - self.n_now, 0.0)
        phi = self.clock(n) - self.clock(self.n_now)
        mean = self.beta[0] + self.beta[1] * phi
        var = self.cov[0, 0] + 2 * phi * self.cov[0, 1] + phi * phi * self.cov[1, 1]
        # the drift's random walk integrated over the clock: var q t (dPhi/dn)^2 / 3 per op
        rate = np.where(t > 0, phi / np.where(t > 0, t, 1.0), 0.0)
        var = var + self.diffusion * t + self.drift_wander * t * (rate * t) ** 2 / 3.0
        return mean, np.sqrt(np.maximum(var, 0.0))

    def draws(self, size: int = DRAWS):
        """Seeded posterior draws of (L now, b now, the t scale factor squared)."""
        if size not in self._draws:
            rng = np.random.default_rng(SEED)
            cov = 0.5 * (self.cov + self.cov.T)
            try:
                chol = np.linalg.cholesky(cov + 1e-300 * np.eye(2))
            except np.linalg.LinAlgError:
                chol = np.diag(np.sqrt(np.maximum(np.diag(cov), 0.0)))
            g = math.sqrt(self.dof) / np.sqrt(rng.chisquare(self.dof, size))
            u = (np.stack([rng.permutation(size) for _ in range(2)], axis=1) + rng.random((size, 2))) / size
            z = special.ndtri(u) @ chol.T * g[:, None]
            self._draws[size] = (self.beta[0] + z[:, 0], self.beta[1] + z[:, 1], g * g)
        return self._draws[size]

    @property
    def closed_form(self) -> bool:
        return self.drift_wander <= 0 and self.clock_power == 1.0

    def crossing_probability(self, limit: float, direction: str, n: np.ndarray) -> np.ndarray:
        """P(the path has crossed ``limit`` by operation ``n``) [-]: its first passage, averaged
        over the posterior."""
        sign = 1.0 if direction == "falling" else -1.0
        t = np.maximum(np.asarray(n, dtype=float) - self.n_now, 0.0)
        if self.closed_form:
            lvl, b, g2 = self.draws()
            delta = sign * (lvl - limit)
            nu = -sign * b / self.scale_ops
            return first_passage(delta[:, None], nu[:, None], (self.diffusion * g2)[:, None], t[None, :],
                                 self.kind).mean(axis=0)
        grid_t, cdf = self._simulated(limit, direction, float(t.max()) if t.size else 0.0)
        return np.interp(t, grid_t, cdf)

    def _simulated(self, limit: float, direction: str, t_max: float):
        key = (limit, direction)
        have = self._draws.get(key)
        if have is None or have[0][-1] < t_max:
            top = max(1e4, 2.0 * t_max)
            grid_t = simulation_grid(top)
            sign = 1.0 if direction == "falling" else -1.0
            lvl, b, g2 = self.draws(self.sim_draws)
            now = self.clock(self.n_now)
            cdf = simulate_passage(sign * (lvl - limit), -sign * b, self.diffusion * g2, self.drift_wander * g2,
                                   grid_t, kind=self.kind, seed=SEED,
                                   clock=lambda tt: self.clock(self.n_now + tt) - now)
            have = (grid_t, np.maximum.accumulate(cdf))
            self._draws[key] = have
        return have


def simulation_grid(top: float) -> np.ndarray:
    """Operations ahead a simulated path is followed on: each of the first 100, then 100
    geometric steps to ``top`` (a crossing's quantile between two points is interpolated)."""
    return np.unique(np.concatenate([[0.0], np.arange(1.0, 100.0), np.geomspace(100.0, top, 100)]))


def share_draws(weights) -> list[int]:
    """Simulated paths per member: SIM_DRAWS shared by weight, at least MIN_SIM_DRAWS each."""
    return [max(MIN_SIM_DRAWS, int(round(SIM_DRAWS * float(w)))) for w in weights]


@dataclass(frozen=True)
class StochasticFamily:
    """The grid posterior of one stochastic family: components and their weights, the family's
    one-step log densities (the grid mixture), and the grid's posterior summary."""

    components: list
    weights: np.ndarray
    log_density: np.ndarray
    grid_weights: dict


def mixed_log_density(lp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the mixture's one-step log densities [m], the final posterior [G]) of grid members' one-step
    log densities ``lp`` [G, m] under a uniform prior: fit i is predicted by the members weighted
    by their posterior given the fits before i."""
    finite = np.isfinite(lp).all(axis=0)
    clean = np.where(finite, lp, 0.0)
    cum = np.cumsum(clean, axis=1)
    before = np.concatenate([np.zeros((lp.shape[0], 1)), cum[:, :-1]], axis=1)
    joint = before + clean
    top = joint.max(axis=0)
    bt = before.max(axis=0)
    mixed = np.log(np.exp(joint - top).sum(axis=0)) + top - (np.log(np.exp(before - bt).sum(axis=0)) + bt)
    final = cum[:, -1] - cum[:, -1].max()
    post = np.exp(final)
    return np.where(finite, mixed, -np.inf), post / post.sum()


def fit_stochastic(n, y, w, nuis, nuis_prior_var, *, start: float, scale_ops: float, prior_sd: float,
                   prior_dof: float, first: int, diffusion_grid=DIFFUSION_GRID,
                   drift_grid=DRIFT_WANDER_GRID, clock_powers=(1.0,)) -> StochasticFamily:
    """The stochastic family through the fits (n [operations], y [unit], w [-]), drift from the
    operation ``start`` on, nuisance columns ``nuis`` [m, q] with prior variances
    ``nuis_prior_var`` [sigma^2 units] (inf: flat), averaged over the grid of (clock power k,
    level wander r, drift wander rho) by its prequential posterior."""
    n, y, w = (np.asarray(a, dtype=float) for a in (n, y, w))
    m = len(n)
    nuis = np.zeros((m, 0)) if nuis is None else np.asarray(nuis, dtype=float).reshape(m, -1)
    h = np.ascontiguousarray(np.hstack([np.ones((m, 1)), np.zeros((m, 1)), nuis]))
    pv = np.concatenate([[DIFFUSE, DIFFUSE], np.minimum(np.asarray(nuis_prior_var, dtype=float), DIFFUSE)])
    dn_ops = np.concatenate([[0.0], np.diff(n)])
    prev = np.concatenate([[n[0]], n[:-1]])
    # the drift (and its wander) acts over the part of each step at or after ``start``
    gate = np.clip(n - np.maximum(prev, start - 1.0), 0.0, None)
    gate = np.where(dn_ops > 0, gate / np.where(dn_ops > 0, dn_ops, 1.0), 0.0)
    d0 = start - 1.0
    y_, w_ = np.ascontiguousarray(y), np.ascontiguousarray(w)
    runs, lps = [], []
    for k in clock_powers:
        phi = clock_of(n, d0, scale_ops, k)
        dphi = np.concatenate([[0.0], np.diff(phi)])
        # the gate is already in Phi (0 before the start): pass the clock's step whole
        for r in diffusion_grid:
            for rho in drift_grid:
                lp, x, pm, ssr, dof = kalman(y_, w_, h, dphi, np.where(dn_ops > 0, 1.0, 0.0) * (gate > 0), pv,
                                             r * dn_ops, rho * dn_ops * gate / scale_ops, prior_sd ** 2,
                                             float(prior_dof), first)
                runs.append((k, r, rho, x, pm, ssr, dof))
                lps.append(lp)
    lp = np.array(lps)
    mixed, post = mixed_log_density(lp)
    order = np.argsort(post)[::-1]
    keep = [i for i in order[:MAX_COMPONENTS] if post[i] >= MIN_WEIGHT] or [int(order[0])]
    comps, wts = [], []
    for i in keep:
        k, r, rho, x, pm, ssr, dof = runs[i]
        if dof <= 0:
            raise ValueError("not enough fits and no prior to estimate the spread")
        s2 = (prior_dof * prior_sd ** 2 + ssr) / dof
        comps.append(WienerFit(beta=np.array([x[0], x[1]]), cov=s2 * pm[:2, :2], dof=float(dof), sd=math.sqrt(s2),
                               diffusion=r * s2, ratio=r, scale_ops=scale_ops, n_now=float(n[-1]),
                               drift_wander=rho * s2 / scale_ops, drift_ratio=rho, clock_power=k, d0=d0))
        wts.append(post[i])
    wts = np.array(wts) / np.sum(wts)
    summary = {}
    for (k, r, rho, *_), p in zip(runs, post):
        summary[("clock", k)] = summary.get(("clock", k), 0.0) + float(p)
        summary[("drift wander", rho)] = summary.get(("drift wander", rho), 0.0) + float(p)
    return StochasticFamily(comps, wts, mixed, summary)


def fit_wiener(n, y, w, nuis, nuis_prior_var, *, start: float, scale_ops: float, prior_sd: float,
               prior_dof: float, first: int, grid=DIFFUSION_GRID, drift_grid=(0.0,)):
    """The most probable Wiener path of the grid (a constant drift unless ``drift_grid`` says
    otherwise): (WienerFit, the family's one-step log densities [m], its level-wander ratio)."""
    fam = fit_stochastic(n, y, w, nuis, nuis_prior_var, start=start, scale_ops=scale_ops, prior_sd=prior_sd,
                         prior_dof=prior_dof, first=first, diffusion_grid=grid, drift_grid=drift_grid)
    best = fam.components[0]
    return best, fam.log_density, best.ratio
