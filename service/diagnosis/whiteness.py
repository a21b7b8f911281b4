"""Ljung–Box portmanteau test (Ljung & Box 1978, Biometrika 65:297) in numpy + scipy."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

LAGS = 10


def ljung_box(x, lags: int = LAGS):
    """(Q, p) for the null "x is white": Q = n(n+2) Σ_{k=1..lags} ρ_k²/(n−k), ρ_k the sample
    autocorrelation about the mean; p from χ² with ``lags`` degrees of freedom (as R's
    ``Box.test(x, lag, type = "Ljung-Box")``)."""
    x = np.asarray(x, float)
    n = x.size
    if n <= lags + 2:
        return 0.0, 1.0
    d = x - x.mean()
    den = float(np.dot(d, d))
    if den <= 0:
        return 0.0, 1.0
    k = np.arange(1, lags + 1)
    rho = np.array([np.dot(d[:-j], d[j:]) for j in k]) / den
    q = float(n * (n + 2) * np.sum(rho * rho / (n - k)))
    return q, float(chi2.sf(q, lags))
