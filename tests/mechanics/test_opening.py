"""Eq. 11 in closed form against an independent integrator (solve_ivp with an α0 event)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from service.mechanics.breaker import TABLE2_RANGES
from service.mechanics.opening import opening_angle, opening_peak_time, simulate_opening
from service.mechanics.opening_kernel import opening_curves


def reference_opening(p, CO, alpha0, t):
    """Two-phase solve_ivp: pre-buffer until the α0 event, then the buffer segment."""
    def pre(_, x):
        return [x[1], -p["AO"] * x[0] + p["BO"] - CO * x[1]]

    def buf(_, x):
        return [x[1], -p["AO"] * x[0] + p["BO"] - (CO + p["DO"]) * x[1] - p["EO"] * (x[0] - alpha0)]

    def hit(_, x):
        return x[0] - alpha0
    hit.terminal, hit.direction = True, 1
    kw = dict(rtol=1e-10, atol=1e-12, method="DOP853")
    s1 = solve_ivp(pre, (0, t[-1]), [0.0, 0.0], events=hit, dense_output=True, **kw)
    out = s1.sol(np.minimum(t, s1.t[-1]))[0]
    if s1.status == 1:
        ts = s1.t_events[0][0]
        s2 = solve_ivp(buf, (ts, t[-1]), s1.y_events[0][0], dense_output=True, **kw)
        out = np.where(t > ts, s2.sol(np.maximum(t, ts))[0], out)
    return out


def random_sets(n, seed):
    rng = np.random.default_rng(seed)
    return [{k: rng.uniform(*TABLE2_RANGES[k]) for k in ("AO", "BO", "DO", "EO")} for _ in range(n)]


T = np.arange(0, 0.08, 1 / 128000)


def test_reference_breaker_matches_solve_ivp(breaker):
    p = breaker.design_parameters()
    tr = simulate_opening(p, T, CO=breaker.CO, alpha0=breaker.alpha0)
    ref = reference_opening(p, breaker.CO, breaker.alpha0, T)
    assert tr.success
    assert np.max(np.abs(tr.theta - ref)) < 1e-6


@pytest.mark.parametrize("p", random_sets(20, seed=11))
def test_random_sets_match_solve_ivp(breaker, p):
    tr = simulate_opening(p, T, CO=breaker.CO, alpha0=breaker.alpha0)
    ref = reference_opening(p, breaker.CO, breaker.alpha0, T)
    assert np.max(np.abs(tr.theta - ref)) < 1e-6


def test_over_damped_segment_is_exact():
    # CO large enough that the pre-buffer segment is over-damped: the complex branch.
    p = {"AO": 2000.0, "BO": 5000.0, "DO": 20.0, "EO": 4000.0}
    CO, alpha0 = 120.0, 0.5
    theta, _, _ = opening_angle(T, *p.values(), CO=CO, alpha0=alpha0)
    assert np.max(np.abs(theta - reference_opening(p, CO, alpha0, T))) < 1e-6


def test_compiled_population_kernel_matches_closed_form(breaker):
    sets = random_sets(8, seed=5)
    X = np.array([[s["AO"], s["BO"], s["DO"], s["EO"], 3e-4] for s in sets])
    t = np.arange(0, 0.07, 32 / 128000)
    fast = opening_curves(X, t, np.zeros_like(t), breaker.CO, breaker.alpha0, True)
    for row, s in zip(fast, sets):
        exact, _, _ = opening_angle(t - 3e-4, *s.values(), CO=breaker.CO, alpha0=breaker.alpha0)
        assert np.max(np.abs(row - np.where(t < 3e-4, 0, exact))) < 1e-9


def test_peak_time_is_where_speed_vanishes(breaker):
    p = breaker.design_parameters()
    tp = float(opening_peak_time(p["AO"], p["BO"], p["DO"], p["EO"], CO=breaker.CO, alpha0=breaker.alpha0))
    _, omega, _ = opening_angle(np.array([tp - 1e-4, tp, tp + 1e-4]), p["AO"], p["BO"], p["DO"], p["EO"],
                                CO=breaker.CO, alpha0=breaker.alpha0)
    assert omega[0] > 0 > omega[2]
    assert abs(omega[1]) < 1e-6


def test_no_buffer_engagement_is_reported(breaker):
    tr = simulate_opening({"AO": 3400, "BO": 1000, "DO": 30, "EO": 4000}, T, CO=breaker.CO,
                          alpha0=breaker.alpha0)
    assert not tr.success and "buffer" in tr.message
