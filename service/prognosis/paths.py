"""Candidate degradation paths, their Bayesian fits, and their leave-future-out predictions.

Pure, numpy/numba only. Every candidate is linear in its coefficients once its shape is fixed:

    y_i = a + b phi_k(d_i) + sum_j h_j s_j(i) + c x_i + e_i,     e_i ~ N(0, sigma^2 / w_i)

- phi_k(d) = (d / S)^k, d the operations since the basis's first fit plus one, S the basis's
  length: k = 1 is the straight line (Lu & Meeker 1993; Gebraeel et al. 2005), k > 1 a power-law
  drift that accelerates (a leak that widens, a spring that tires faster as it ages).
- s_j: nuisance columns the caller adds (the annual harmonics of a breaker without temperature,
  a separate level for the fits before the change point); their value at the forecast is 0.
- c x: the temperature slope's error, common to every fit, with a N(0, common_var) prior.

sigma^2 has the conjugate scaled-inverse-chi^2 prior of the baseline (s0 from nu0 degrees of
freedom), the other coefficients a flat prior, so each candidate's level is Student t.

Each candidate's one-step-ahead predictive density of every fit after the first few, given the
fits before it (leave-future-out, Burkner, Gabry & Vehtari 2020), comes from recursive least
squares: one pass, O(m p^2). stacking.py turns these into model weights (pseudo-BMA+).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

# Power-law exponents of the candidate paths: the straight line and two accelerating drifts
# (a rate that grows in proportion to sqrt(d) and to d). A rate growing faster than d within
# the basis is not a maintenance question any more but a failure in progress.
SHAPES = (1.0, 1.5, 2.0)
# The flat prior is approximated by this precision on the coefficients of unit-scaled columns
# (phi in [0, 1]); it only makes the first recursive steps invertible.
FLAT_PRECISION = 1e-8


@dataclass(frozen=True)
class PathFit:
    """Posterior of one candidate path.

    shape : its exponent k; beta : posterior mean of the coefficients [a, b, nuisances..., c]
    cov : posterior scale matrix of beta (Student t with ``dof``); sd : posterior sigma [unit]
    scale_ops : S, the basis's length [operations]; d0 : the operation count with d = 0
    extra_var : variance added to the level, common to every future point (e.g. the residual's
        unexplained low-frequency variance) [unit^2]
    """

    shape: float
    beta: np.ndarray
    cov: np.ndarray
    dof: float
    sd: float
    scale_ops: float
    d0: float
    extra_var: float = 0.0
    variant: str = "free"

    def level(self, n: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(mean, scale) of the true level after operation ``n`` [unit]; Student t with ``dof``."""
        phi = np.maximum(np.asarray(n, dtype=float) - self.d0, 0.0) / self.scale_ops
        phi = shape_of(phi, self.shape)
        mean = self.beta[0] + self.beta[1] * phi
        var = self.cov[0, 0] + 2.0 * phi * self.cov[0, 1] + phi * phi * self.cov[1, 1] + self.extra_var
        return mean, np.sqrt(np.maximum(var, 0.0))


def shape_column(n: np.ndarray, d0: float, scale_ops: float, k: float) -> np.ndarray:
    return shape_of(np.maximum(n - d0, 0.0) / scale_ops, k)


def shape_of(x: np.ndarray, k: float) -> np.ndarray:
    """phi_k(x) of x = d / S [-]: the power x^k for k > 0; for k < 0 the exponential approach
    |k| (1 - exp(-x / |k|)), a rate that decays with the time constant |k| S (slope 1 at x = 0)."""
    if k > 0:
        return x ** k
    return -k * (1.0 - np.exp(x / k))


def fit_path(x: np.ndarray, y: np.ndarray, w: np.ndarray, prior_precision: np.ndarray, *,
             prior_sd: float, prior_dof: float, shape: float, scale_ops: float, d0: float,
             ) -> PathFit:
    """Conjugate posterior of one candidate. x: design [m, p]; prior_precision: per coefficient,
    in units of 1/sigma^2 at the baseline's sd (0: flat)."""
    xtw = x.T * w
    a_mat = xtw @ x
    rhs = xtw @ y
    a_mat = a_mat + np.diag(prior_precision)
    try:
        inv = np.linalg.inv(a_mat)
    except np.linalg.LinAlgError:
        raise ValueError("the fits do not determine a trend") from None
    beta = inv @ rhs
    resid = y - x @ beta
    ssr = float((w * resid * resid).sum())
    ssr += float((prior_precision * beta * beta).sum())
    dof = prior_dof + len(y) - 2
    if dof <= 0:
        raise ValueError("not enough fits and no prior to estimate the spread")
    s2 = (prior_dof * prior_sd ** 2 + ssr) / dof
    return PathFit(shape=shape, beta=beta, cov=s2 * inv, dof=float(dof), sd=math.sqrt(s2),
                   scale_ops=scale_ops, d0=d0)


@njit(cache=True)
def lfo_log_density(x, y, w, prior_precision, prior_sd2, prior_dof, first):
    """Leave-future-out one-step-ahead log predictive densities (Student t) of y[i] given
    y[:i], for i >= ``first``; -inf before (Burkner, Gabry & Vehtari 2020). Recursive least
    squares with a Sherman-Morrison update of the inverse and the running weighted residual sum
    of squares (Plackett 1950)."""
    m, p = x.shape
    out = np.full(m, -np.inf)
    pinv = np.zeros((p, p))
    for j in range(p):
        pinv[j, j] = 1.0 / prior_precision[j]
    beta = np.zeros(p)
    ssr = 0.0
    for i in range(m):
        xi = x[i]
        px = pinv @ xi
        denom = 1.0 / w[i] + xi @ px
        e = y[i] - xi @ beta
        dof = prior_dof + i - 2.0
        if i >= first and dof > 0:
            v = (prior_dof * prior_sd2 + ssr) / dof * denom
            out[i] = (math.lgamma(0.5 * (dof + 1.0)) - math.lgamma(0.5 * dof)
                      - 0.5 * math.log(dof * math.pi * v) - 0.5 * (dof + 1.0) * math.log1p(e * e / v / dof))
        gain = px / denom
        beta = beta + gain * e
        ssr += e * e / denom
        pinv = pinv - np.outer(gain, px)
    return out
