"""The stochastic paths (wiener.py, passage.py), the change points (bocpd.py) and the dates (dates.py)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from service.prognosis.bocpd import fit_change_points
from service.prognosis.dates import days_to_operations, operation_rate, recent_gaps
from service.prognosis.paths import lfo_log_density
from service.prognosis.passage import first_passage, simulate_passage
from service.prognosis.wiener import fit_stochastic, fit_wiener, kalman, mixed_log_density


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
    lp, x, *_ = kalman(y, w, h, dn, gate, np.array([1e8, 1e8]), np.zeros(m), np.zeros(m), 0.01, 10.0, 5)
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


def test_the_change_points_find_the_change_of_slope_and_its_segment():
    rng = np.random.default_rng(5)
    m = 120
    n = np.arange(m, dtype=float)
    y = 10 - 0.001 * n - 0.03 * np.maximum(n - 80, 0) + 0.05 * rng.standard_normal(m)
    cp = fit_change_points(n, y, np.ones(m), None, [], centre=10.0, scale_ops=float(m), prior_sd=0.05,
                           prior_dof=20.0, first=5)
    best = max(zip(cp.components, cp.weights), key=lambda cw: cw[1])[0]
    assert best.kind == "sloped" and abs(best.start_n - 80) <= 4
    assert best.beta[1] / m == pytest.approx(-0.031, abs=0.006), "the slope since the change, not the average"
    assert abs(cp.last_change - 80) <= 4 and np.isfinite(cp.log_density[5:]).all()
    assert sum(cp.hazard_posterior.values()) == pytest.approx(1.0, abs=1e-3) and 0 < cp.hazard < 0.011


def test_a_leak_that_stops_is_a_flat_segment_and_crosses_only_through_a_change_still_to_come():
    rng = np.random.default_rng(8)
    m = 300
    n = np.arange(m, dtype=float)
    true = 10 - 0.01 * np.minimum(n, 150)  # 1.5 down, then it holds at 8.5
    y = true + 0.05 * rng.standard_normal(m)
    cp = fit_change_points(n, y, np.ones(m), None, [], centre=10.0, scale_ops=float(m), prior_sd=0.05,
                           prior_dof=20.0, first=5)
    assert cp.flat_now > 0.9, "the leak stopped: the current segment is flat"
    seg = max(zip(cp.components, cp.weights), key=lambda cw: cw[1])[0]
    # within 10 operations of the stop: the leak moves the level by 2 sd in 10
    assert seg.kind == "flat" and abs(seg.start_n - 150) <= 10
    # a limit at 7.5: without a change it is never reached; a change of pace still may come
    t, cdf, share = seg.simulated(7.5, "falling", 5000.0)
    assert cdf[np.searchsorted(t, 50)] < 0.05 and 0.0 < np.interp(5000, t, cdf) < 0.95 and share == 1.0


def test_the_family_density_is_the_posterior_mixture_of_its_members():
    lp = np.log(np.array([[0.5, 0.2, 0.9], [0.1, 0.4, 0.3]]))
    mixed, post = mixed_log_density(lp)
    w1 = np.array([0.5, 0.5])
    w2 = w1 * np.exp(lp[:, 0]) / (w1 * np.exp(lp[:, 0])).sum()
    w3 = w2 * np.exp(lp[:, 1]) / (w2 * np.exp(lp[:, 1])).sum()
    want = [np.log((w1 * np.exp(lp[:, 0])).sum()), np.log((w2 * np.exp(lp[:, 1])).sum()),
            np.log((w3 * np.exp(lp[:, 2])).sum())]
    assert np.allclose(mixed, want) and post == pytest.approx(w3 * np.exp(lp[:, 2]) / (w3 * np.exp(lp[:, 2])).sum())


def test_the_simulated_passage_is_the_inverse_gaussian_when_the_drift_holds():
    k = 4000
    delta, nu, q = np.full(k, 4.0), np.full(k, 0.05), np.full(k, 0.04)
    t = np.arange(0.0, 401.0)
    sim = simulate_passage(delta, nu, q, np.zeros(k), t)
    exact = first_passage(4.0, 0.05, 0.04, t)
    assert np.abs(sim - exact).max() < 0.03


def test_the_drift_wander_widens_the_crossing_both_ways():
    k = 4000
    delta, nu, q = np.full(k, 4.0), np.full(k, 0.05), np.full(k, 0.01)
    t = np.arange(0.0, 2001.0)
    fixed = simulate_passage(delta, nu, q, np.zeros(k), t)
    wander = simulate_passage(delta, nu, q, np.full(k, 1e-5), t)
    assert wander[60] > fixed[60] + 0.05, "a drift that may speed up crosses earlier"
    assert wander[100] < fixed[100] - 0.05, "a drift that may slow crosses later"
    assert fixed[-1] == 1.0 and wander[-1] < 0.99, "a drift that may stop may never cross"


def test_the_drift_wander_is_found_where_the_leak_stops_and_not_in_a_straight_leak():
    rng = np.random.default_rng(12)
    m = 300
    n = np.arange(m, dtype=float)
    noise = 0.05 * rng.standard_normal(m)
    straight = 10 - 0.005 * n + noise
    stops = 10 - 0.01 * np.minimum(n, 150) + noise
    kw = {"start": 0.0, "scale_ops": float(m), "prior_sd": 0.05, "prior_dof": 20.0, "first": 5}
    a = fit_stochastic(n, straight, np.ones(m), None, [], **kw).grid_weights
    b = fit_stochastic(n, stops, np.ones(m), None, [], **kw).grid_weights
    assert a[("drift wander", 0.0)] > 0.5 and b[("drift wander", 0.0)] < 0.1


def test_a_slowing_path_is_found_on_its_own_clock():
    rng = np.random.default_rng(13)
    m = 300
    n = np.arange(m, dtype=float)
    clock = lambda x: (1.0 + x / m) ** 0.5 - 1.0  # noqa: E731  (the shifted power, k = 1/2)
    y = 10 - 4.0 * clock(n + 1) + 0.05 * rng.standard_normal(m)
    fam = fit_stochastic(n, y, np.ones(m), None, [], start=0.0, scale_ops=float(m), prior_sd=0.05, prior_dof=20.0,
                         first=5, drift_grid=(0.0,), clock_powers=(0.25, 0.5, 0.75, 1.0))
    assert fam.grid_weights[("clock", 0.5)] > 0.5 and fam.grid_weights[("clock", 1.0)] < 0.05
    c = fam.components[0]
    # it slows: the next 300 operations lose what the clock says (4 (sqrt 3 - sqrt 2) = 1.27), not
    # the last 300's 1.66
    want = -4.0 * (clock(n[-1] + 301) - clock(n[-1] + 1))
    assert c.level(n[-1] + 300)[0] - c.level(n[-1])[0] == pytest.approx(want, abs=0.15)


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
