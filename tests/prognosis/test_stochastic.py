"""The stochastic paths (wiener.py), the change-point path (changepoint.py) and the dates (dates.py)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from service.prognosis.changepoint import fit_change_point
from service.prognosis.dates import days_to_operations, operation_rate, recent_gaps
from service.prognosis.paths import lfo_log_density
from service.prognosis.wiener import first_passage, fit_wiener, kalman


@pytest.mark.parametrize("delta,nu,q", [(5.0, 0.1, 0.05), (2.0, 0.02, 0.01), (10.0, 0.5, 2.0)])
def test_wiener_first_passage_is_inverse_gaussian(delta, nu, q):
    t = np.array([1.0, 10.0, delta / nu, 3 * delta / nu])
    mean, shape = delta / nu, delta ** 2 / q
    expected = stats.invgauss.cdf(t, mu=mean / shape, scale=shape)
    assert np.allclose(first_passage(delta, nu, q, t), expected, atol=1e-9)


def test_gamma_first_passage_is_the_gamma_tail():
    delta, nu, q, t = 3.0, 0.05, 0.02, np.array([10.0, 60.0, 200.0])
    expected = stats.gamma.sf(delta, a=nu * nu * t / q, scale=q / nu)
    assert np.allclose(first_passage(delta, nu, q, t, "gamma"), expected, atol=1e-12)


def test_first_passage_crossed_and_deterministic():
    assert first_passage(-1.0, 0.1, 0.01, 5.0) == 1.0
    assert first_passage(1.0, 0.1, 0.0, np.array([9.0, 10.0])).tolist() == [0.0, 1.0]


def test_wiener_passage_matches_a_simulated_walk():
    rng = np.random.default_rng(7)
    delta, nu, q, steps = 4.0, 0.05, 0.04, 400
    walk = np.cumsum(nu + np.sqrt(q) * rng.standard_normal((20000, steps)), axis=1)
    hit = (walk >= delta).any(axis=1).mean()
    # the discrete walk misses excursions between steps: it crosses slightly less often
    assert hit == pytest.approx(float(first_passage(delta, nu, q, steps)), abs=0.03)


def test_kalman_without_diffusion_is_the_recursive_least_squares_line():
    rng = np.random.default_rng(3)
    m = 60
    n = np.arange(m, dtype=float)
    y = 10 - 0.02 * n + 0.1 * rng.standard_normal(m)
    w = np.ones(m)
    h = np.column_stack([np.ones(m), np.zeros(m)])
    dn = np.concatenate([[0.0], np.diff(n)]) / m
    gate = np.ones(m)
    lp, x, *_ = kalman(y, w, h, dn, gate, np.array([1e8, 1e8]), np.zeros(m), 0.01, 10.0, 5)
    xr = np.column_stack([np.ones(m), n / m])
    ref = lfo_log_density(xr, y, w, np.full(2, 1e-8), 0.01, 10.0, 5)
    assert np.allclose(lp[5:], ref[5:], atol=1e-3)
    assert x[1] / m == pytest.approx(-0.02, abs=0.005)


def test_the_diffusion_is_found_in_a_wandering_history_and_not_in_a_straight_one():
    rng = np.random.default_rng(11)
    m = 300
    n = np.arange(m, dtype=float)
    noise = 0.1 * rng.standard_normal(m)
    straight = 10 - 0.002 * n + noise
    wander = 10 + np.cumsum(0.05 * rng.standard_normal(m)) + noise
    kw = {"start": 0.0, "scale_ops": float(m), "prior_sd": 0.1, "prior_dof": 20.0, "first": 5}
    _, _, r_straight = fit_wiener(n, straight, np.ones(m), None, [], **kw)
    fit, _, r_wander = fit_wiener(n, wander, np.ones(m), None, [], **kw)
    assert r_straight <= 1e-3 and r_wander >= 0.03
    assert fit.level(n[-1] + 100)[1] > fit.level(n[-1])[1], "the wandering still to come widens the level"


def test_the_change_point_path_finds_the_change_of_slope():
    rng = np.random.default_rng(5)
    m = 120
    n = np.arange(m, dtype=float)
    y = 10 - 0.001 * n - 0.03 * np.maximum(n - 80, 0) + 0.05 * rng.standard_normal(m)
    fits, lp = fit_change_point(n, y, np.ones(m), None, np.zeros(0), d0=-1.0, scale_ops=float(m),
                                prior_sd=0.05, prior_dof=20.0, first=5)
    best = max(fits, key=lambda fw: fw[1])[0]
    slope = best.beta[1] / m
    assert slope == pytest.approx(-0.031, abs=0.006), "the slope since the change, not the average"
    assert np.isfinite(lp[5:]).all()


def test_the_rate_counts_the_gap_that_straddles_the_year():
    # a long idle gap, then openings every 2 days: the last year holds 150 gaps, one straddling
    t = np.concatenate([[0.0], 400.0 + np.arange(0, 500, 2.0)])
    g = recent_gaps(t)
    assert g.size == 183 and g.max() == 2.0
    assert operation_rate(t) == pytest.approx(0.5)
    idle = np.concatenate([[0.0], 300.0 + np.arange(0, 200, 2.0)])  # the idle gap straddles the year
    assert operation_rate(idle) < 0.5


def test_dates_carry_the_spread_of_the_duty_cycle():
    rng = np.random.default_rng(2)
    regular = np.full(300, 1.0)
    bursty = np.concatenate([np.concatenate([rng.exponential(0.05, 20), [20.0]]) for _ in range(15)])
    bursty *= regular.sum() / bursty.sum()  # the same mean gap
    ops = np.full(500, 100.0)
    d_reg, d_burst = days_to_operations(ops, regular), days_to_operations(ops, bursty)
    assert np.allclose(d_reg, 100.0)
    assert d_burst.mean() == pytest.approx(100.0 * bursty.mean(), rel=0.1)
    assert np.quantile(d_burst, 0.95) - np.quantile(d_burst, 0.05) > 20.0
    assert days_to_operations(np.array([np.inf, 0.0]), regular).tolist() == [np.inf, 0.0]
