"""An interval as wide as the estimate's real spread (issue 44 item 1): the covariance of a fit is
the sandwich of the residual it leaves, with that residual's AR(p) correlation
(service/estimation/uncertainty.py), floored at the idle-noise one. Checked on least-squares
problems whose answer is known in closed form; the coverage on repeated operations is measured by
bench/interval_repeat.py (and, for the estimator of the previous round,
bench/interval_coverage.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import toeplitz

from service.estimation.uncertainty import correlated_covariance, covariance, residual_ar, toeplitz_quadratic


def ar(n, phi, sd, rng, burn=500):
    e = np.zeros(n + burn)
    v = rng.normal(0, sd, n + burn)
    for i in range(len(phi), n + burn):
        e[i] = sum(p * e[i - 1 - k] for k, p in enumerate(phi)) + v[i]
    return e[burn:]


def level(n):
    """Estimating a level (J = a column of ones): var(mean) = long-run variance / n."""
    return np.ones((n, 1)), np.array([1.0])


@pytest.mark.parametrize("seed", range(5))
def test_white_residual_keeps_the_idle_noise_interval(seed):
    rng = np.random.default_rng(seed)
    J, scale = level(4000)
    e = rng.normal(0, 1e-3, J.shape[0])
    e -= e.mean()  # the least-squares residual: orthogonal to J
    unc = correlated_covariance(J, e, 1e-3, scale)
    white = covariance(J, 1e-3, scale)
    assert white.stderr[0] <= unc.stderr[0] <= 1.1 * white.stderr[0]


@pytest.mark.parametrize("rho", [0.5, 0.8])
def test_an_ar1_residual_widens_the_interval_to_its_long_run_variance(rho):
    rng = np.random.default_rng(5)
    J, scale = level(20000)
    e = ar(J.shape[0], [rho], 1e-3 * np.sqrt(1 - rho**2), rng)  # marginal σ 1 mrad = the idle σ
    unc = correlated_covariance(J, e - e.mean(), 1e-3, scale)
    ratio = unc.stderr[0] / covariance(J, 1e-3, scale).stderr[0]
    assert unc.noise["basis"] == "residual in motion" and unc.noise["ar_order"] >= 1
    assert ratio == pytest.approx(np.sqrt((1 + rho) / (1 - rho)), rel=0.15)


def test_a_ringing_residual_is_an_ar2_and_its_long_run_variance_is_used():
    rng = np.random.default_rng(8)
    phi = [1.6, -0.8]  # complex roots: a damped oscillation, like a struck torsional mode
    J, scale = level(20000)
    e = ar(J.shape[0], phi, 1e-3, rng)
    unc = correlated_covariance(J, e - e.mean(), e.std(), scale)
    assert unc.noise["ar_order"] >= 2
    long_run_sd = 1e-3 / abs(1 - sum(phi))  # σ_v / (1 − φ1 − φ2)
    assert unc.stderr[0] * np.sqrt(J.shape[0]) == pytest.approx(long_run_sd, rel=0.2)


def test_the_interval_never_narrows_below_the_idle_noise_one():
    rng = np.random.default_rng(9)
    J, scale = level(4000)
    e = ar(J.shape[0], [-0.6], 1e-3, rng)  # negative correlation: the sandwich alone is narrower
    unc = correlated_covariance(J, e - e.mean(), 1e-3, scale)
    assert unc.stderr[0] == pytest.approx(covariance(J, 1e-3, scale).stderr[0])
    assert unc.noise["widening"] == [1.0] and unc.noise["basis"] == "idle samples"


def test_the_ar_order_is_chosen_by_bic():
    rng = np.random.default_rng(2)
    assert residual_ar(rng.normal(size=3000))[0] == 0
    p, phi, gam = residual_ar(ar(3000, [1.6, -0.8], 1.0, rng))
    assert p >= 2 and phi[:2] == pytest.approx([1.6, -0.8], abs=0.1)
    assert gam[0] > 0 and abs(gam[5]) < gam[0]


def test_the_toeplitz_product_equals_the_explicit_one():
    rng = np.random.default_rng(4)
    J = rng.normal(size=(60, 3))
    gam = 0.7 ** np.arange(60)
    assert toeplitz_quadratic(J, gam) == pytest.approx(J.T @ toeplitz(gam) @ J)


def test_a_residual_too_short_or_not_finite_falls_back_to_the_idle_noise_interval():
    J, scale = np.ones((5, 2)), np.array([1.0, 1.0])
    J[:, 1] = np.arange(5)
    unc = correlated_covariance(J, np.full(5, np.nan), 1e-3, scale)
    assert unc.noise is None
    assert np.allclose(unc.stderr, covariance(J, 1e-3, scale).stderr)
