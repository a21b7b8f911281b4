"""Local least-squares polish and the Jacobian-based uncertainty of a fit."""

from __future__ import annotations

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
    """

    stderr: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    condition_number: float
    identifiable: bool


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
