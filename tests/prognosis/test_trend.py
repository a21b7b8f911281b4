"""The degradation trend and its crossing quantiles (service.prognosis.trend)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.prognosis.trend import Trend, fit_trend


def test_quantiles_solve_the_crossing_probability():
    """Each closed-form quantile is where the crossing probability first reaches p (checked on a
    fine grid), for random posteriors, both directions."""
    rng = np.random.default_rng(5)
    for _ in range(40):
        tr = Trend(a=rng.normal(30, 1), b=-abs(rng.normal(0, 0.3)) * rng.uniform(), n_ref=0.0,
                   v_aa=rng.uniform(0.01, 1), v_ab=rng.uniform(-1e-3, 1e-3), v_bb=rng.uniform(1e-5, 1e-2),
                   dof=rng.uniform(5, 50), sd=1.0, m=10)
        n_now = rng.uniform(0, 20)
        grid = np.linspace(n_now, n_now + 3000, 150_001)
        for direction, limit, sign in (("falling", 27.0, 1), ("rising", 33.0, -1)):
            t = tr if sign == 1 else Trend(**{**tr.__dict__, "b": -tr.b})
            f = t.crossing_probability(limit, direction, grid)
            for p in (0.05, 0.5, 0.95):
                q = t.crossing_quantile(limit, direction, p, n_now=n_now)
                hit = np.flatnonzero(f >= p)
                if hit.size:
                    assert q == pytest.approx(grid[hit[0]], abs=0.05)
                else:
                    assert q > 3000 + n_now


def test_exact_line_recovers_slope_and_crossing():
    n = np.arange(50.0)
    y = 40.0 - 0.2 * n + np.random.default_rng(1).normal(0, 0.4, 50)
    tr = fit_trend(n, y, np.ones(50), prior_sd=0.4, prior_dof=100)
    assert tr.b == pytest.approx(-0.2, abs=0.02)
    median = tr.crossing_quantile(30.0, "falling", 0.5, n_now=49)
    assert median == pytest.approx(50.0, abs=5.0)
    lo, hi = (tr.crossing_quantile(30.0, "falling", p, n_now=49) for p in (0.05, 0.95))
    assert lo < median < hi


def test_flat_trend_never_crosses_at_its_median():
    n = np.arange(400.0)
    y = 40.0 + np.random.default_rng(2).normal(0, 0.6, 400)
    tr = fit_trend(n, y, np.ones(400), prior_sd=0.6, prior_dof=20)
    assert tr.crossing_quantile(30.0, "falling", 0.5, n_now=399) > 10_000


def test_common_mode_term_widens_the_level_not_the_centre():
    rng = np.random.default_rng(3)
    n = np.arange(60.0)
    dt = 20.0 * np.sin(n / 20.0)
    y = 40.0 - 0.1 * n + rng.normal(0, 0.4, 60)
    plain = fit_trend(n, y, np.ones(60), prior_sd=0.4, prior_dof=50)
    shared = fit_trend(n, y, np.ones(60), prior_sd=0.4, prior_dof=50, common=dt, common_var=0.02 ** 2)
    assert shared.b == pytest.approx(plain.b, abs=0.01)
    assert shared.level(100.0)[1] > plain.level(100.0)[1]


@pytest.mark.parametrize("args, words", [
    (([1.0], [1.0], [1.0]), "at least two fits"),
    (([1.0, 1.0], [1.0, 2.0], [1.0, 1.0]), "at least two fits"),
    (([1.0, 2.0], [1.0, math.nan], [1.0, 1.0]), "must be finite"),
    (([1.0, 2.0], [1.0, 2.0], [1.0, 0.0]), "weight positive"),
])
def test_bad_input_in_words(args, words):
    with pytest.raises(ValueError, match=words):
        fit_trend(*map(np.array, args), prior_sd=1.0, prior_dof=10)
