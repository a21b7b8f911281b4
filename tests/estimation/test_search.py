"""CMA-ES stage machinery: stopping rules, seeds, range re-adaptation, bad candidates."""

import numpy as np

from service.estimation import cmaes
from service.estimation.parameter_space import ParameterSpace
from service.mechanics.opening_kernel import opening_curves


def test_explicit_seed_is_reproducible_and_seeds_differ():
    def f(X):
        return np.sum((X - 0.3) ** 2, axis=1)
    a = cmaes.minimize(f, 3, seed=5)
    b = cmaes.minimize(f, 3, seed=5)
    c = cmaes.minimize(f, 3, seed=6)
    assert np.array_equal(a.x_best, b.x_best) and a.iterations == b.iterations
    assert not np.array_equal(a.x_best, c.x_best)
    assert np.allclose(a.x_best, 0.3, atol=1e-3)


def test_stops_on_one_of_the_paper_rules():
    res = cmaes.minimize(lambda X: np.sum((X - 0.6) ** 2, axis=1), 2, seed=1)
    assert res.stop_reason in ("tol_x", "tol_fun", "tol_sigma")
    assert res.iterations < 1000


def test_failed_candidates_are_ranked_worst():
    def f(X):
        out = np.sum((X - 0.5) ** 2, axis=1)
        out[X[:, 0] > 0.7] = np.nan  # a simulation that failed
        return out
    res = cmaes.minimize(f, 2, seed=2)
    assert np.isfinite(res.f_best) and np.allclose(res.x_best, 0.5, atol=1e-3)


def test_edge_stop_reports_the_pinned_mean():
    res = cmaes.minimize(lambda X: np.sum((X - np.array([1.3, 0.5])) ** 2, axis=1), 2, seed=3,
                         edge_dims=(0,))
    assert res.stop_reason == "edge" and res.x_mean[0] > 0.99


def test_readaptation_moves_the_range_and_keeps_positive_parameters_positive():
    space = ParameterSpace.from_ranges(("EO", "DO"), {"EO": (4000.0, 6000.0), "DO": (10.0, 50.0)})
    assert space.edges_hit([4001.0, 30.0]) == ["EO"]
    moved = space.readapted([4001.0, 30.0])
    assert moved.lo[0] < 3951 < moved.hi[0] and moved.hi[0] - moved.lo[0] == 2000.0
    assert (moved.lo[1], moved.hi[1]) == (10.0, 50.0)
    low = space.readapted([4001.0, 10.1])
    assert low.lo[1] > 0


def test_kernel_returns_nan_not_an_exception_for_a_zero_spring():
    X = np.array([[0.0, 4800.0, 1e-4], [3400.0, 4800.0, 1e-4]])
    t = np.linspace(0, 0.02, 50)
    out = opening_curves(X, t, np.zeros_like(t), 92.6, 0.698, False)
    assert not np.all(np.isfinite(out[0])) and np.all(np.isfinite(out[1]))
