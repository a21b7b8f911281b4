"""The Gauss–Newton joint refit (service/diagnosis/linearised.py): it recovers a shared effect
from the reduced fit's tangent, never makes a fit worse, and its hold-out shrink is a share."""

import numpy as np
import pytest

from service.diagnosis.hypotheses import fit_hypothesis, none_fit
from service.diagnosis.linearised import gauss_newton, holdout_shrink, refit
from service.diagnosis.windows import prepare
from service.prototypes.a import groups as ga


@pytest.fixture(scope="module")
def orifice(breaker):
    rng = np.random.default_rng(131)
    unit = ga.make_unit(rng, effects={"orifice_buffer": 0.6})
    caps = [ga.simulate_capture(unit, "open", conditions=ga.draw_conditions(rng), rng=rng)[0] for _ in range(3)]
    return prepare(caps, breaker, "open")


def test_refit_lowers_the_joint_chi2_towards_the_noise(orifice):
    w = orifice
    start = fit_hypothesis(w, ("orifice_buffer",), [np.array([0.2, 1.0, 0.5, 0.0])], refine_nfev=4)
    h = refit(w, start, iters=3)
    none = none_fit(w)
    assert h.chi2 <= start.chi2
    assert h.chi2 < 0.5 * none.chi2                     # the buffer explains most of the gap
    assert h.chi2 < w.n + 8.0 * np.sqrt(2.0 * w.n)      # and leaves about the noise
    assert 0.3 < h.phi["orifice_buffer"][0] < 1.2       # the generator's 0.6, units' ±3 % traded against it


def test_gauss_newton_never_raises_the_cost(orifice):
    w = orifice
    z0 = np.array([0.6, 1.0, 0.5, 0.0])
    z, xs, rs, _ = gauss_newton(w, ("orifice_buffer",), z0, w.captures, iters=0)
    c0 = sum(float(r @ r) for r in rs)
    z, xs, rs, _ = gauss_newton(w, ("orifice_buffer",), z0, w.captures, iters=2)
    assert sum(float(r @ r) for r in rs) <= c0


@pytest.mark.xfail(strict=True, reason="issue 54: holdout_shrink is ill-posed when a shape parameter sits just off its "
                   "bound (main's own code gives shrinks 0.70/0.15/0.66 with the buffer's free travel at its bound "
                   "0.03 and 0.68/0.16/-4.0 at 0.0297, chi2 2781 vs 2779); the refit here now stops off the bound "
                   "(the reduced fit's Jacobian on the coarser grid moved the path), median 0.04")
def test_holdout_shrink_is_a_share_per_capture(orifice):
    w = orifice
    h = refit(w, fit_hypothesis(w, ("orifice_buffer",), [np.array([0.5, 1.0, 0.5, 0.0])]), iters=3)
    s = holdout_shrink(w, h)
    assert len(s) == len(w.captures)
    assert all(v <= 1.0 for v in s)
    assert np.median(s) > 0.5                            # each capture predicted from the others
    assert holdout_shrink(w, none_fit(w)) is None
