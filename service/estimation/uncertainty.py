"""Local least-squares polish and the Jacobian-based uncertainty of a fit.

The covariance of a fit is the sandwich (JᵀJ)⁻¹ JᵀΣJ (JᵀJ)⁻¹ of the residual the fit actually
leaves in motion, with its correlation: Σ is the Toeplitz autocovariance of an autoregressive
model of that residual (the "AR-whitened residual"), of order p chosen by Schwarz's criterion
(BIC) up to min(20, n/10), fitted by Yule–Walker (Levinson–Durbin). An AR(p) with p ≥ 2 follows
the damped ringing of a torsional mode as well as a slow misfit, which a Bartlett-weighted
Newey–West sum with Andrews' AR(1) bandwidth does not (bench/interval_methods.py compares both;
docs/estimation.md). A residual of white noise selects p = 0, Σ = σ²I: the classical σ²(JᵀJ)⁻¹,
whose σ from the idle samples stays the floor of each standard error: where the model fits to the
noise the interval is as before. The fit hands it the residual less its smooth, repeating part
(service/estimation/model_bias.py): the interval stands for what varies between operations.

- G. Schwarz, "Estimating the dimension of a model", Ann. Statist. 6 (1978) 461–464.
- W. J. den Haan, A. Levin, "A practitioner's guide to robust covariance matrix estimation",
  Handbook of Statistics 15 (1997) 299–342 (the parametric, AR-based long-run covariance).
- W. K. Newey, K. D. West, Econometrica 55 (1987) 703–708; D. W. K. Andrews, Econometrica 59
  (1991) 817–858 (the kernel estimator it was compared with).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

Z95 = 1.959963984540054
ILL_CONDITIONED = 1e6   # condition number of the model parameters' correlation matrix
HIGH_CORRELATION = 0.995


@dataclass(frozen=True)
class Uncertainty:
    """Covariance summary of the estimated parameters (physical units).

    Attributes
    ----------
    stderr : ndarray
        Standard errors.
    covariance : ndarray
    correlation : ndarray
    condition_number : float
        Of the correlation-scaled normal matrix; large means ill-conditioned.
    identifiable : bool
    noise : dict or None
        Which noise the interval stands for: ``basis`` ("idle samples" when the residual in
        motion widens no interval, else "residual in motion"), the residual's AR order and
        lag-1 autocorrelation, and ``widening``: each standard error over the idle-noise one (≥ 1).
    """

    stderr: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    condition_number: float
    identifiable: bool
    noise: dict | None = None


@dataclass(frozen=True)
class Polish:
    x: np.ndarray
    jacobian: np.ndarray
    evaluations: int
    success: bool
    message: str


def polish(residuals, x0, lower, upper, scale) -> Polish:
    """Refine ``x0`` with a trust-region least-squares solve (scipy), within physical bounds."""
    x0 = np.clip(np.asarray(x0, dtype=float), lower + 1e-12 * scale, upper - 1e-12 * scale)
    res = least_squares(residuals, x0, bounds=(lower, upper), x_scale=scale, method="trf",
                        xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=200, diff_step=1e-7)
    evaluations = int(res.nfev) + int(res.njev or 0) * x0.size
    return Polish(res.x, res.jac, evaluations, bool(res.success), str(res.message))


def covariance(jacobian, noise_sd: float, scale, n_model: int | None = None) -> Uncertainty:
    """Parameter covariance σ²(JᵀJ)⁻¹ for residuals with per-sample noise ``noise_sd``.

    ``jacobian`` is d(residual)/d(parameter) in physical units; ``scale`` their typical size,
    used only to condition the inversion. Identifiability is judged on the first ``n_model``
    parameters' marginal correlation (nuisance parameters such as the onset delay follow).
    """
    J = np.asarray(jacobian, dtype=float) * scale[None, :]
    A = J.T @ J
    d = np.sqrt(np.diag(A))
    d = np.where(d > 0, d, 1.0)
    R = A / np.outer(d, d)
    try:
        Rinv = np.linalg.inv(R)
    except np.linalg.LinAlgError:
        Rinv = np.linalg.pinv(R)
    cov_scaled = Rinv / np.outer(d, d) * noise_sd**2
    cov = cov_scaled * np.outer(scale, scale)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    corr = np.nan_to_num(corr)
    k = len(sd) if n_model is None else n_model
    block = corr[:k, :k]
    cond = float(np.linalg.cond(block))
    off = np.abs(block - np.eye(k))
    identifiable = bool(cond < ILL_CONDITIONED and (off.max() if off.size else 0) < HIGH_CORRELATION)
    return Uncertainty(sd, cov, corr, cond, identifiable)



MAX_AR_ORDER = 20  # and at most n/10: the residual's AR order is chosen by BIC below this


def residual_ar(e: np.ndarray, max_order: int | None = None) -> tuple[int, np.ndarray, np.ndarray]:
    """AR(p) model of a residual ``e`` (n,), p by BIC (Schwarz 1978), Yule–Walker estimates.

    Returns (p, φ (p,), γ (n,)): the order, the coefficients and the model's autocovariance at
    lags 0..n−1 [unit²] (the sample's for lags ≤ p, the Yule–Walker recursion beyond). One
    Levinson–Durbin recursion gives every order's coefficients and innovation variance at once.
    """
    n = e.size
    top = int(min(MAX_AR_ORDER if max_order is None else max_order, n // 10))
    g = np.array([e[:n - k] @ e[k:] for k in range(top + 1)]) / n
    gl = g.tolist()  # the recursion on Python floats: a few hundred scalar steps, no array overhead
    best = (math.log(gl[0]) if gl[0] > 0 else -math.inf, 0, [])
    phi, s2 = [], gl[0]
    for p in range(1, top + 1):
        if not s2 > 0:
            break
        k = (gl[p] - sum(f * gl[p - 1 - i] for i, f in enumerate(phi))) / s2
        if not abs(k) < 1.0:  # not positive definite (rounding): no higher order is valid
            break
        phi = [f - k * phi[-1 - i] for i, f in enumerate(phi)] + [k]
        s2 = s2 * (1.0 - k * k)
        if not s2 > 0:
            break
        bic = math.log(s2) + math.log(n) * p / n
        if bic < best[0]:
            best = (bic, p, phi)
    _, p, phi = best
    phi = np.array(phi, dtype=float)
    gam = np.zeros(n)
    gam[:p + 1] = g[:p + 1]
    if p > 0 and n > p + 1:
        # γ(k) = Σ φᵢ γ(k − i) beyond lag p: an all-pole recursion, run by lfilter from the last p lags
        from scipy.signal import lfilter, lfiltic

        a = np.concatenate([[1.0], -phi])
        zi = lfiltic([1.0], a, gam[p:0:-1])
        gam[p + 1:] = lfilter([1.0], a, np.zeros(n - p - 1), zi=zi)[0]
        # decayed: the rest is zero to rounding (and toeplitz_quadratic stops at the last lag kept)
        k = np.arange(n)
        small = np.nonzero((np.abs(gam) < 1e-9 * g[0]) & (k > 2 * p))[0]
        if small.size:
            gam[small[0]:] = 0.0
    return p, phi, gam


def toeplitz_quadratic(J: np.ndarray, gam: np.ndarray) -> np.ndarray:
    """JᵀΣJ for the Toeplitz Σ of autocovariances ``gam`` (lags 0..n−1), without forming Σ."""
    M = gam[0] * (J.T @ J)
    last = int(np.max(np.nonzero(gam)[0])) if np.any(gam) else 0
    for k in range(1, min(last, J.shape[0] - 1) + 1):
        if gam[k] != 0.0:
            g = J[k:].T @ J[:-k]
            M += gam[k] * (g + g.T)
    return M


def correlated_covariance(jacobian, residual, noise_sd: float, scale, n_model: int | None = None,
                          variance_factor: float = 1.0) -> Uncertainty:
    """The fit's covariance from the residual it leaves, with its correlation (module docstring).

    ``jacobian`` (n, p) and ``residual`` (n,) are the fit's weighted residual rows and their
    derivatives, in time order, at the estimate [rad, rad per parameter unit]; ``noise_sd`` the
    idle samples' σ [rad]. ``variance_factor`` scales the residual's covariance (the residual
    less a mean of k earlier ones has (1 + 1/k) times the variance it stands for:
    service.estimation.model_bias). Each standard error is at least the classical one (σ²(JᵀJ)⁻¹).
    """
    white = covariance(jacobian, noise_sd, scale, n_model)
    J = np.asarray(jacobian, dtype=float) * scale[None, :]
    e = np.asarray(residual, dtype=float)
    if e.size != J.shape[0] or e.size < 10 * J.shape[1] or not np.all(np.isfinite(e)) or not np.any(e):
        return white
    A = J.T @ J
    d = np.sqrt(np.diag(A))
    d = np.where(d > 0, d, 1.0)
    try:
        Ainv = np.linalg.inv(A / np.outer(d, d)) / np.outer(d, d)
    except np.linalg.LinAlgError:
        Ainv = np.linalg.pinv(A / np.outer(d, d)) / np.outer(d, d)
    order, phi, gam = residual_ar(e)
    cov_r = Ainv @ toeplitz_quadratic(J, gam) @ Ainv * np.outer(scale, scale) * variance_factor
    sd_r = np.sqrt(np.clip(np.diag(cov_r), 0, None))
    widen = np.where(sd_r > white.stderr, sd_r / np.where(white.stderr > 0, white.stderr, 1.0), 1.0)
    sd = white.stderr * widen
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.nan_to_num(cov_r / np.outer(sd_r, sd_r))
    np.fill_diagonal(corr, 1.0)
    k = len(sd) if n_model is None else n_model
    noise = {"method": "AR(p) residual sandwich", "basis": "residual in motion" if widen[:k].max() > 1.0
             else "idle samples", "idle_noise_rad": float(noise_sd),
             "residual_rms_rad": float(np.sqrt(np.mean(e * e))), "ar_order": int(order),
             "residual_lag1_autocorrelation": float(gam[1] / gam[0]) if gam[0] > 0 else 0.0,
             "widening": [float(w) for w in widen[:k]]}
    return Uncertainty(sd, corr * np.outer(sd, sd), white.correlation if widen.max() == 1.0 else corr,
                       white.condition_number, white.identifiable, noise)
