"""The in-motion noise of a capture (issue 36, step 2 of ``predictive``): the AR spectrum of what
a per-capture spline leaves beside the nuisance, floored at the sensor's white level, applied as
a zero-phase filter 1/√S(f) to the residual and to every column."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline

AR_ORDER = 8           # the in-motion noise spectrum (vibration modes: two poles each)
NOISE_KNOT_S = 2.0e-3  # [s] knots of the per-capture spline whose residual is the noise (> ~250 Hz)


def yule_walker(e: np.ndarray, order: int = AR_ORDER):
    """AR coefficients a (e_t = Σ a_k e_{t−k} + u_t) and the innovation variance, Yule–Walker."""
    e = np.asarray(e, float) - float(np.mean(e))
    n = e.size
    r = np.array([float(np.dot(e[: n - k], e[k:])) / n for k in range(order + 1)])
    if r[0] <= 0:
        return np.zeros(order), 1.0
    from scipy.linalg import solve_toeplitz

    try:
        a = solve_toeplitz(r[:order], r[1: order + 1])
    except np.linalg.LinAlgError:
        return np.zeros(order), float(r[0])
    if not np.all(np.abs(np.roots(np.concatenate([[1.0], -a]))) < 1.0):   # keep the filter stable
        return np.zeros(order), float(r[0])
    return a, float(max(r[0] - np.dot(a, r[1: order + 1]), 1e-12 * r[0]))


def spline_basis(t: np.ndarray, lo: float, hi: float, step: float) -> np.ndarray:
    """Cubic B-splines on [lo, hi] with knots every ``step``, at ``t`` (clipped)."""
    interior = np.arange(lo, hi, step)[1:]
    knots = np.concatenate([[lo] * 4, interior, [hi] * 4])
    return BSpline.design_matrix(np.clip(t, lo, hi), knots, 3).toarray()


def _orth(A: np.ndarray, tol: float = 1e-8) -> np.ndarray:
    if A.shape[1] == 0:
        return A
    nrm = np.maximum(np.linalg.norm(A, axis=0), 1e-300)
    U, s, _ = np.linalg.svd(A / nrm, full_matrices=False)
    return U[:, s > s[0] * tol] if s.size and s[0] > 0 else U[:, :0]


def _prewhiten(cw, n_drop: int = 0):
    """The capture's in-motion noise filter: the AR spectrum of what a per-capture spline of
    ``NOISE_KNOT_S`` knots leaves beside the nuisance (the vibration and the sensor noise above
    ~250 Hz; the smooth gap is in the spline), floored at the sensor's white level (1, the
    pre-trigger σ: below the spline's band nothing can be estimated, and no noise is quieter than
    the sensor's), applied as a zero-phase filter 1/√S(f). Returns (filter, (a, innovation sd))."""
    t = cw.data.t
    B = spline_basis(t, float(t[0]), float(t[-1]) + 1e-9, max(NOISE_KNOT_S, 4 * float(np.median(np.diff(t)))))
    B = B * cw.data.weight[:, None]
    A = np.column_stack([cw.Q, B])
    from scipy.linalg import lstsq as _lstsq
    coef = _lstsq(A, cw.r, lapack_driver="gelsy", check_finite=False)[0]   # pivoted QR: rank-revealing, fast
    e = cw.r - A @ coef
    dof = max(e.size - min(A.shape[1], e.size - 1), 1)
    a, v = yule_walker(e, AR_ORDER)
    v *= e.size / dof
    n = cw.r.size
    nfft = int(2 ** np.ceil(np.log2(2 * n)))
    w = np.linspace(0.0, np.pi, nfft // 2 + 1)
    Aw = np.ones_like(w, dtype=complex)
    for k, ak in enumerate(a, start=1):
        Aw -= ak * np.exp(-1j * k * w)
    S = np.maximum(v / np.abs(Aw) ** 2, 1.0)
    H = 1.0 / np.sqrt(S)

    def f(x):
        X = np.fft.rfft(np.asarray(x, float), nfft, axis=0)
        Y = np.fft.irfft(X * (H[:, None] if X.ndim == 2 else H), nfft, axis=0)[:n]
        return Y[n_drop:]
    return f, (a.tolist(), float(np.sqrt(v)))


