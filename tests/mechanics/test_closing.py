"""Eq. 7 (compiled RK4 over a population) against solve_ivp on the plain right-hand side."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from service.mechanics.breaker import TABLE2_RANGES
from service.mechanics.cam_profile import CamProfile, CamProfileError
from service.mechanics.closing import closing_angle, closing_rhs, simulate_closing
from service.mechanics.coordinates import operation_coordinate, travel_from_coordinate

T = np.arange(0, 0.06, 1 / 128000)


def reference_closing(p, breaker, t):
    g = breaker.closing_geometry
    sol = solve_ivp(lambda tt, x: closing_rhs(tt, x, p, breaker.cam, g), (0, t[-1]),
                    [g.theta1_start, 0.0], t_eval=t, rtol=1e-10, atol=1e-12, method="DOP853")
    return breaker.cam.evaluate(sol.y[0])[0]


def random_sets(n, seed, breaker):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        p = {k: rng.uniform(*TABLE2_RANGES[k]) for k in ("AC", "BC", "CC")}
        p["DC"] = rng.uniform(*TABLE2_RANGES["AO"])
        tr = simulate_closing(p, T, cam=breaker.cam, geometry=breaker.closing_geometry)
        if tr.success and np.isfinite(tr.t_peak):
            out.append(p)
    return out


def _check(p, breaker):
    tr = simulate_closing(p, T, cam=breaker.cam, geometry=breaker.closing_geometry)
    ref = reference_closing(p, breaker, T)
    valid = T <= tr.t_peak
    assert tr.success
    assert np.max(np.abs(tr.theta[valid] - ref[valid])) < 1e-6


def test_reference_breaker_matches_solve_ivp(breaker):
    _check(breaker.design_parameters(), breaker)


def test_twenty_random_sets_match_solve_ivp(breaker):
    for p in random_sets(20, 3, breaker):
        _check(p, breaker)


def test_population_rows_are_independent(breaker):
    p = breaker.design_parameters()
    P = np.array([[p["AC"], p["BC"], p["CC"], p["DC"]], [p["AC"] * 0.9, p["BC"], p["CC"], p["DC"]]])
    both, _, _, _ = closing_angle(T, P, cam=breaker.cam, geometry=breaker.closing_geometry)
    single, _, _, _ = closing_angle(T, P[1:], cam=breaker.cam, geometry=breaker.closing_geometry)
    np.testing.assert_array_equal(both[1], single[0])
    assert np.max(np.abs(both[0] - both[1])) > 0.01


def test_a_weak_spring_stalls(breaker):
    p = dict(breaker.design_parameters(), AC=6000.0)
    tr = simulate_closing(p, T, cam=breaker.cam, geometry=breaker.closing_geometry)
    assert not tr.success and "stalled" in tr.message


def test_closes_in_about_36_ms(breaker):
    tr = simulate_closing(breaker.design_parameters(), T, cam=breaker.cam, geometry=breaker.closing_geometry)
    assert 0.030 < tr.t_peak < 0.042
    assert tr.theta.max() == pytest.approx(1.0, abs=1e-3)


def test_cam_interpolant_has_continuous_first_and_second_derivatives(breaker):
    knots = breaker.cam.theta1[1:-1]
    eps = 1e-9
    _, d1_lo, d2_lo = breaker.cam.evaluate(knots - eps)
    _, d1_hi, d2_hi = breaker.cam.evaluate(knots + eps)
    assert np.max(np.abs(d1_lo - d1_hi)) < 1e-6
    assert np.max(np.abs(d2_lo - d2_hi)) < 1e-5


def test_cam_table_that_is_not_monotone_is_refused():
    x = np.linspace(0, 3, 20)
    y = np.clip(x - 1, 0, 1)
    y[10] = y[9] - 0.05
    with pytest.raises(CamProfileError, match="not monotone"):
        CamProfile.from_table(x, y)


def test_travel_coordinate_round_trip():
    travel = np.array([0.0, 0.3, 1.0])
    assert np.allclose(operation_coordinate(travel, "close", 1.0), [1.0, 0.7, 0.0])
    for op in ("open", "close"):
        assert np.allclose(travel_from_coordinate(operation_coordinate(travel, op, 1.0), op, 1.0), travel)
    with pytest.raises(ValueError):
        operation_coordinate(travel, "trip", 1.0)
