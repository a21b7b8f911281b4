"""A linear degradation path with Bayesian updating, and the distribution of its crossing time.

Pure, numpy/scipy only. The temperature-compensated value of a parameter after operation n is

    y_n = a + b n + e_n,          e_n ~ N(0, sigma^2 / w_n)

(a linear random-coefficient degradation model, Lu & Meeker 1993; its Bayesian updating and
residual-life distribution, Gebraeel, Lawley, Li & Ryan 2005). sigma^2 has a conjugate
scaled-inverse-chi^2 prior: the breaker's own baseline, whose run-to-run sd s0 was learnt from
nu0 degrees of freedom. With a flat prior on (a, b) the posterior of (a, b) is a bivariate
Student t with nu0 + m - 2 degrees of freedom, and the level L(n) = a + b n is Student t with

    mean  a^ + b^ n,     scale^2  sigma^2 [1 n] (X'WX)^-1 [1 n]'.

The path crosses a lower limit D by operation n when L(n) <= D, so the crossing time N has
P(N <= n) = P(L(n) <= D) (Gebraeel et al. 2005, eq. 12). Its p-quantile solves
(D - L^(n))^2 = t_p^2 scale^2(n), a quadratic in n. When the trend is not significant at level
p the quadratic has no root past now: that quantile is "never".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class Trend:
    """Posterior of the degradation path of one parameter.

    a, b : level at ``n_ref`` [unit] and slope [unit/operation] (posterior means)
    n_ref : reference operation count [operations]
    v_aa, v_ab, v_bb : posterior scale matrix of (a, b) [unit^2, unit^2/op, unit^2/op^2]
    dof : degrees of freedom of the Student t [-]
    sd : posterior estimate of the run-to-run sd sigma [unit]
    m : fits in the basis
    """

    a: float
    b: float
    n_ref: float
    v_aa: float
    v_ab: float
    v_bb: float
    dof: float
    sd: float
    m: int

    def level(self, n: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(mean, scale) of the true level after operation ``n`` [unit]; Student t with ``dof``."""
        d = np.asarray(n, dtype=float) - self.n_ref
        var = self.v_aa + 2.0 * d * self.v_ab + d * d * self.v_bb
        return self.a + self.b * d, np.sqrt(np.maximum(var, 0.0))

    def crossing_probability(self, limit: float, direction: str, n: np.ndarray | float) -> np.ndarray:
        """P(the level has crossed ``limit`` by operation ``n``) [-]; direction "falling" for a
        lower limit, "rising" for an upper one."""
        mean, scale = self.level(n)
        sign = 1.0 if direction == "falling" else -1.0
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(scale > 0, sign * (limit - mean) / np.where(scale > 0, scale, 1.0),
                         np.where(sign * (limit - mean) >= 0, np.inf, -np.inf))
        return stats.t.cdf(z, self.dof)

    def crossing_quantile(self, limit: float, direction: str, p: float, *, n_now: float) -> float:
        """The operation count by which the level has crossed ``limit`` with probability ``p``
        [operations]; ``n_now`` when it has already, ``inf`` when the trend never gets there."""
        if not 0.0 < p < 1.0:
            raise ValueError(f"p must be in (0, 1), got {p}")
        if self.crossing_probability(limit, direction, n_now) >= p:
            return float(n_now)
        t = 0.0 if p == 0.5 else float(stats.t.ppf(p, self.dof))
        sign = 1.0 if direction == "falling" else -1.0
        # g(d) = sign (limit - a - b d) = t scale(d), d = n - n_ref: square and solve.
        c0, c1 = sign * (limit - self.a), -sign * self.b
        qa = c1 * c1 - t * t * self.v_bb
        qb = 2.0 * (c0 * c1 - t * t * self.v_ab)
        qc = c0 * c0 - t * t * self.v_aa
        # At p = 0.5 (t = 0) the quadratic is a perfect square: its double root is g's zero.
        roots = ([-c0 / c1] if c1 != 0 else []) if p == 0.5 else _real_roots(qa, qb, qc)
        d_now = n_now - self.n_ref
        # Keep the roots past now on the right branch (g has the sign of t there), nearest first.
        ok = [d for d in roots if d > d_now and (t == 0.0 or (c0 + c1 * d) * t >= 0)]
        return float(min(ok) + self.n_ref) if ok else math.inf


def _real_roots(qa: float, qb: float, qc: float) -> list[float]:
    if abs(qa) < 1e-300:
        return [-qc / qb] if qb != 0 else []
    disc = qb * qb - 4.0 * qa * qc
    if disc < -1e-12 * qb * qb:
        return []
    disc = max(disc, 0.0)  # a double root that rounding pushed below zero
    r = math.sqrt(disc)
    # Numerically stable form of the quadratic formula.
    q = -0.5 * (qb + math.copysign(r, qb))
    out = [q / qa]
    if q != 0:
        out.append(qc / q)
    return out


def fit_trend(n: np.ndarray, y: np.ndarray, weight: np.ndarray, *, prior_sd: float,
              prior_dof: float, common: np.ndarray | None = None, common_var: float = 0.0) -> Trend:
    """Posterior of y = a + b n + c x + e, e ~ N(0, sigma^2 / weight), with sigma^2's prior from
    the baseline (``prior_sd`` [unit] learnt with ``prior_dof`` degrees of freedom).

    n : operation counts [operations]; y : compensated values [unit]; weight : relative
    precisions [-] (1 for a fit as good as the baseline's typical one). Needs two distinct n.
    common, common_var : an error shared by every fit in proportion to ``common`` (x), with a
        N(0, common_var) prior on its coefficient c. For temperature-compensated values x is
        T - T_mean [K] and common_var the learnt slope's variance [(unit/K)^2]: the slope's error
        is the same for every fit, so it is a term of the model, not independent noise. The
        level a + b n is marginalised over c.
    """
    n, y, w = (np.asarray(v, dtype=float) for v in (n, y, weight))
    if not (n.shape == y.shape == w.shape) or n.ndim != 1:
        raise ValueError("n, y and weight must be 1-D arrays of the same length")
    if len(n) < 2 or np.ptp(n) <= 0:
        raise ValueError("a trend needs at least two fits at different operation counts")
    if not (np.isfinite(n).all() and np.isfinite(y).all() and (w > 0).all() and np.isfinite(w).all()):
        raise ValueError("n, y must be finite and weight positive")
    if not (prior_sd > 0 and prior_dof >= 0):
        raise ValueError(f"prior_sd must be > 0 and prior_dof >= 0, got {prior_sd}, {prior_dof}")
    n_ref = float((w * n).sum() / w.sum())
    cols = [np.ones_like(n), n - n_ref]
    use_common = common is not None and common_var > 0
    if use_common:
        cols.append(np.asarray(common, dtype=float))
    x = np.stack(cols, axis=1)
    xtw = x.T * w
    a_mat = xtw @ x
    if use_common:  # the prior precision of c, in units of sigma^2 (at the baseline's sd)
        a_mat[2, 2] += prior_sd ** 2 / common_var
    try:
        inv = np.linalg.inv(a_mat)
    except np.linalg.LinAlgError:
        raise ValueError("the fits do not determine a trend") from None
    beta = inv @ (xtw @ y)
    resid = y - x @ beta
    ssr = float((w * resid * resid).sum())
    if use_common:
        ssr += float(beta[2] ** 2 * prior_sd ** 2 / common_var)
    dof = prior_dof + len(n) - 2
    if dof <= 0:
        raise ValueError("not enough fits and no prior to estimate the spread")
    s2 = (prior_dof * prior_sd ** 2 + ssr) / dof
    return Trend(a=float(beta[0]), b=float(beta[1]), n_ref=n_ref, v_aa=s2 * inv[0, 0],
                 v_ab=s2 * inv[0, 1], v_bb=s2 * inv[1, 1], dof=float(dof), sd=math.sqrt(s2), m=len(n))
