"""Ljung–Box in numpy + scipy against R's Box.test output.

Reference: R ``Box.test(y1, lag = k, type = "Ljung-Box")`` on y1 = the first 100 draws of
numpy's legacy RandomState(9876543).standard_normal, as recorded in statsmodels'
test_diagnostic.py::test_acorr_ljung_box_against_r (X-squared 0.15685, 5.4737, 10.508;
p 0.6921, 0.3608, 0.3971 for lags 1, 5, 10)."""

import numpy as np
import pytest

from service.diagnosis.whiteness import ljung_box


@pytest.mark.parametrize("lags,q_r,p_r", [(1, 0.15685, 0.6921), (5, 5.4737, 0.3608), (10, 10.508, 0.3971)])
def test_ljung_box_matches_r(lags, q_r, p_r):
    y1 = np.random.RandomState(9876543).standard_normal(100)
    q, p = ljung_box(y1, lags)
    assert q == pytest.approx(q_r, rel=1e-3)
    assert p == pytest.approx(p_r, rel=1e-3)


def test_structured_residual_is_not_white():
    t = np.linspace(0, 1, 400)
    q, p = ljung_box(np.sin(6 * t) + 0.1 * np.random.default_rng(0).normal(size=t.size))
    assert p < 1e-6
