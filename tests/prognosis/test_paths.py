"""Candidate paths, their leave-future-out densities and their pseudo-BMA+ weights
(service.prognosis.paths, service.prognosis.averaging)."""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from service.prognosis.averaging import pseudo_bma_plus_weights
from service.prognosis.paths import FLAT_PRECISION, fit_path, lfo_log_density, shape_column


def design(n, k):
    return np.stack([np.ones_like(n), shape_column(n, -1.0, float(len(n)), k)], axis=1)


def test_recursive_densities_equal_refitting_on_each_prefix():
    """The one-pass recursion gives, for every fit, the Student-t density of a fresh conjugate
    fit to the fits before it (the definition of leave-future-out)."""
    rng = np.random.default_rng(4)
    n = np.arange(40, dtype=float)
    y = 10.0 - 0.05 * n + rng.normal(0, 0.3, 40)
    w = rng.uniform(0.5, 1.5, 40)
    x = design(n, 1.0)
    prec = np.full(2, FLAT_PRECISION)
    lp = lfo_log_density(x, y, w, prec, 0.3 ** 2, 20.0, 6)
    assert np.all(np.isneginf(lp[:6]))
    for i in range(6, 40):
        f = fit_path(x[:i], y[:i], w[:i], np.zeros(2), prior_sd=0.3, prior_dof=20.0, shape=1.0,
                     scale_ops=40.0, d0=-1.0)
        mean = x[i] @ f.beta
        var = x[i] @ f.cov @ x[i] + f.sd ** 2 / w[i]
        expect = stats.t.logpdf(y[i], f.dof, loc=mean, scale=math.sqrt(var))
        assert abs(lp[i] - expect) < 1e-5, (i, lp[i], expect)


def test_weights_follow_the_shape_that_predicts_and_stay_spread_when_they_cannot_tell():
    rng = np.random.default_rng(9)
    n = np.arange(120, dtype=float)
    prec = np.full(2, FLAT_PRECISION)

    def weights(y, sd):
        lps = [lfo_log_density(design(n, k), y, np.ones(120), prec, sd ** 2, 30.0, 8) for k in (1.0, 2.0)]
        return pseudo_bma_plus_weights(np.array(lps))

    curved = 10.0 - 4.0 * (n / 120) ** 2 + rng.normal(0, 0.05, 120)
    assert weights(curved, 0.05)[1] > 0.95  # a clear acceleration: the power-2 path
    straight = 10.0 - 4.0 * (n / 120) + rng.normal(0, 0.05, 120)
    assert weights(straight, 0.05)[0] > 0.95
    # the same straight drift buried in noise 40x larger: neither shape predicts better
    noisy = 10.0 - 4.0 * (n / 120) + rng.normal(0, 2.0, 120)
    w = weights(noisy, 2.0)
    assert 0.1 < w[0] < 0.9, w


def test_pseudo_bma_plus_is_deterministic_and_sums_to_one():
    lp = np.random.default_rng(1).normal(-1, 0.5, (3, 50))
    a, b = pseudo_bma_plus_weights(lp), pseudo_bma_plus_weights(lp)
    assert np.array_equal(a, b) and abs(a.sum() - 1) < 1e-12 and (a > 0).all()
    assert np.allclose(pseudo_bma_plus_weights(np.full((2, 0), -1.0)), [0.5, 0.5])
