"""Stochastic degradation paths: a Wiener process with drift, and a gamma process, whose diffusion
is estimated from the history itself.

Pure, numpy/numba/scipy only. The compensated value after operation n is

    y_i = L(n_i) + sum_j h_j s_j(i) + c x_i + e_i,       e_i ~ N(0, sigma^2 / w_i)
    L(n) = L(n') + b (n - n') / S + W(n) - W(n'),        W a Brownian motion, var r sigma^2 per op

(Whitmore 1995; Si, Wang, Hu & Zhou 2012: a Wiener degradation path with drift b / S per
operation, observed with measurement error). The drift acts from the basis's first fit on; the
wandering W acts everywhere, so a level that wanders (greasing, settling, seal swell, a
temperature effect the compensation does not follow) is noise, not trend. s_j and c x are the
nuisance columns of paths.py (a level of its own before the change point, the annual harmonics,
the temperature slope's error), constant states of the filter.

The Kalman filter (one pass, O(m p^2)) gives the state at the last fit (L now, b and their
covariance) and every fit's one-step-ahead predictive density given the fits before it; with
sigma^2 conjugate (the baseline's scaled-inverse-chi^2 prior, as in paths.py) these are Student
t. The diffusion ratio r = var(W per op) / sigma^2 is chosen on a log grid (0 included: a smooth
path) by the sum of those log densities, the prequential marginal likelihood (Dawid 1984).

Crossing a lower limit D from the level L now with drift nu = -b / S per op and diffusion
var q per op: the first passage time is inverse Gaussian (Si et al. 2012, eq. 6; Chhikara &
Folks 1989),

    P(T <= t) = Phi((nu t - delta) / sqrt(q t)) + exp(2 nu delta / q) Phi((-nu t - delta) / sqrt(q t)),
    delta = L - D,

averaged over the posterior of (L, b, sigma) by seeded Monte Carlo draws (a Student t draw of
the state). For a parameter whose limit has one side, a gamma process with the same mean and
variance per operation (van Noortwijk 2009: a monotone path, shape nu^2 / q and scale q / nu per
operation) gives a second candidate sharing the filter: the path only moves one way, so it has
crossed by t when its loss exceeds delta, P(T <= t) = Q(nu^2 t / q, delta nu / q), Q the
regularised upper incomplete gamma function. Their one-step densities are the same (the filter's),
so the averaging gives them equal shares of the stochastic weight: a history of a few hundred fits
cannot tell a Wiener from a gamma path, only their first passages differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy import special

# Diffusion ratios r = var(W per operation) / sigma^2 tried. A level that wanders by one
# run-to-run sd in 10 000 operations is r = 1e-4; by one sd per operation, r = 1.
DIFFUSION_GRID = (0.0, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0)
DRAWS = 128  # stratified (Latin hypercube) normal draws
SEED = 2012
DIFFUSE = 1e8  # prior variance of the level and drift [sigma^2 units]: flat in practice


@njit(cache=True)
def kalman(y, w, h, dn, gate, prior_var, r, prior_sd2, prior_dof, first):
    """One pass of the Kalman filter of the model above, every variance in units of sigma^2.

    y [m], w [m] : values [unit] and relative precisions [-]; h [m, p] : observation rows (column
    0 the level, column 1 zero: the drift enters the transition, the rest nuisances, constant
    states); dn [m] : step to each fit in basis lengths S [-] (0 for the first); gate [m] : the
    share of that step at or after the drift's start [-]; prior_var [p] : initial variances;
    r [m] : the wandering's variance over each step (ratio times operations); prior_sd2,
    prior_dof : sigma^2's scaled-inverse-chi^2 prior; first : first fit whose density is scored.
    Returns (log predictive densities [m], -inf before ``first``; state mean [p]; its scale
    matrix [p, p]; the innovations' weighted sum of squares; the degrees of freedom).
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
            # predict: L += b dn gate; var(L) += r dn
            d = dn[i] * gate[i]
            if d != 0.0:
                x[0] += x[1] * d
                col = pm[:, 1].copy()
                pm[:, 0] += d * col
                row = pm[1, :].copy()
                pm[0, :] += d * row
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


@dataclass(frozen=True)
class WienerFit:
    """Posterior of a stochastic path at the last fit.

    beta : [L now, b] posterior mean [unit, unit per S operations]; cov : their scale matrix
    (Student t with ``dof``) [unit^2]; sd : posterior sigma [unit]; diffusion : r sigma^2 per
    operation [unit^2]; scale_ops : S [operations]; n_now : the last fit's operation count
    kind : "wiener" | "gamma"
    """

    beta: np.ndarray
    cov: np.ndarray
    dof: float
    sd: float
    diffusion: float
    ratio: float
    scale_ops: float
    n_now: float
    kind: str = "wiener"
    variant: str = "stochastic"
    shape: float = 1.0
    _draws: dict = field(default_factory=dict, compare=False, repr=False)

    def level(self, n):
        """(mean, scale) of the level after operation ``n`` [unit] (Student t with ``dof``);
        ahead of now its scale carries the wandering still to come."""
        t = np.asarray(n, dtype=float) - self.n_now
        phi = t / self.scale_ops
        mean = self.beta[0] + self.beta[1] * phi
        var = self.cov[0, 0] + 2 * phi * self.cov[0, 1] + phi * phi * self.cov[1, 1]
        var = var + self.diffusion * np.maximum(t, 0.0)
        return mean, np.sqrt(np.maximum(var, 0.0))

    def draws(self):
        """Seeded posterior draws of (L now, nu per op toward a falling limit's sign +, q per op)."""
        if "d" not in self._draws:
            rng = np.random.default_rng(SEED)
            cov = 0.5 * (self.cov + self.cov.T)
            try:
                chol = np.linalg.cholesky(cov + 1e-300 * np.eye(2))
            except np.linalg.LinAlgError:
                chol = np.diag(np.sqrt(np.maximum(np.diag(cov), 0.0)))
            g = math.sqrt(self.dof / 1.0) / np.sqrt(rng.chisquare(self.dof, DRAWS))  # t scale factor
            u = (np.stack([rng.permutation(DRAWS) for _ in range(2)], axis=1) + rng.random((DRAWS, 2))) / DRAWS
            z = special.ndtri(u) @ chol.T * g[:, None]
            lvl = self.beta[0] + z[:, 0]
            b = self.beta[1] + z[:, 1]
            q = self.diffusion * g * g
            self._draws["d"] = (lvl, b / self.scale_ops, q)
        return self._draws["d"]

    def crossing_probability(self, limit: float, direction: str, n: np.ndarray) -> np.ndarray:
        """P(the path has crossed ``limit`` by operation ``n``) [-]: first passage, averaged over
        the posterior draws."""
        lvl, rate, q = self.draws()
        sign = 1.0 if direction == "falling" else -1.0
        delta = sign * (lvl - limit)  # distance to go [unit], > 0 not crossed
        nu = -sign * rate  # speed toward the limit [unit/op]
        t = np.maximum(np.asarray(n, dtype=float) - self.n_now, 0.0)
        return first_passage(delta[:, None], nu[:, None], q[:, None], t[None, :], self.kind).mean(axis=0)


def first_passage(delta, nu, q, t, kind="wiener"):
    """P(T <= t) of a path at distance ``delta`` [unit] from its limit, drift ``nu`` toward it
    [unit/op], diffusion variance ``q`` per op [unit^2/op], after ``t`` operations (arrays,
    broadcast). Wiener: the inverse Gaussian first passage (defective when nu <= 0); gamma: a
    monotone path with the same mean and variance per op; q = 0: the deterministic crossing."""
    delta, nu, q, t = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (delta, nu, q, t)))
    out = np.where(delta <= 0, 1.0, 0.0)
    live = delta > 0
    det = live & (q <= 0)
    out = np.where(det & (nu * t >= delta), 1.0, out)
    st = live & (q > 0) & (t > 0)
    if kind == "gamma":
        ok = st & (nu > 0)
        a = np.where(ok, nu * nu * t / np.where(ok, q, 1.0), 1.0)
        x = np.where(ok, delta * nu / np.where(ok, q, 1.0), 1.0)
        return np.where(ok, special.gammaincc(a, x), out)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        sq = np.sqrt(np.where(st, q * t, 1.0))
        p1 = special.ndtr((nu * t - delta) / sq)
        expo = 2.0 * nu * delta / np.where(st, q, 1.0) + special.log_ndtr((-nu * t - delta) / sq)
        p2 = np.exp(np.minimum(expo, 0.0))
    return np.where(st, np.clip(p1 + p2, 0.0, 1.0), out)


def fit_wiener(n, y, w, nuis, nuis_prior_var, *, start: float, scale_ops: float, prior_sd: float,
               prior_dof: float, first: int, grid=DIFFUSION_GRID):
    """The Wiener path through the fits (n [operations], y [unit], w [-]), drift from the
    operation ``start`` on, nuisance columns ``nuis`` [m, q] with prior variances
    ``nuis_prior_var`` [sigma^2 units] (inf: flat). Chooses the diffusion ratio on ``grid`` by the
    prequential likelihood. Returns (WienerFit, log densities [m], chosen ratio)."""
    n, y, w = (np.asarray(a, dtype=float) for a in (n, y, w))
    m = len(n)
    nuis = np.zeros((m, 0)) if nuis is None else np.asarray(nuis, dtype=float).reshape(m, -1)
    h = np.hstack([np.ones((m, 1)), np.zeros((m, 1)), nuis])
    pv = np.concatenate([[DIFFUSE, DIFFUSE], np.minimum(np.asarray(nuis_prior_var, dtype=float), DIFFUSE)])
    dn_ops = np.concatenate([[0.0], np.diff(n)])
    # the drift acts over the part of each step at or after ``start``
    gate = np.clip(n - np.maximum(np.concatenate([[n[0]], n[:-1]]), start - 1.0), 0.0, None)
    gate = np.where(dn_ops > 0, gate / np.where(dn_ops > 0, dn_ops, 1.0), 0.0)
    dn = dn_ops / scale_ops
    h, y_, w_ = np.ascontiguousarray(h), np.ascontiguousarray(y), np.ascontiguousarray(w)
    best = None
    for r in grid:
        lp, x, pm, ssr, dof = kalman(y_, w_, h, dn, gate, pv, r * dn_ops, prior_sd ** 2, float(prior_dof), first)
        score = float(lp[np.isfinite(lp)].sum())
        if best is None or score > best[0] + 1e-9:
            best = (score, r, lp, x, pm, ssr, dof)
    _, r, lp, x, pm, ssr, dof = best
    if dof <= 0:
        raise ValueError("not enough fits and no prior to estimate the spread")
    s2 = (prior_dof * prior_sd ** 2 + ssr) / dof
    fit = WienerFit(beta=np.array([x[0], x[1]]), cov=s2 * pm[:2, :2], dof=float(dof), sd=math.sqrt(s2),
                    diffusion=r * s2, ratio=r, scale_ops=scale_ops, n_now=float(n[-1]))
    return fit, lp, r
