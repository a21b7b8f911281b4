"""Issue 36: the capture as the unit of evidence (service/diagnosis/predictive.py), its parts
checked against direct computation, and the sensor's nuisance."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from service.diagnosis import predictive as P


def _units(rng, n_units=5, rows=40, k=3, beta=None, noise=1.0):
    X = [rng.normal(size=(rows, k)) for _ in range(n_units)]
    beta = np.zeros(k) if beta is None else np.asarray(beta, float)
    return [(x @ beta + noise * rng.normal(size=rows), {"f": x}) for x in X]


def test_loo_density_is_the_direct_gaussian_predictive():
    """Woodbury closed form = fit on the other units (posterior under the g prior), then the
    held-out unit's Gaussian predictive density, computed densely."""
    rng = np.random.default_rng(1)
    units = _units(rng, beta=[0.3, -0.2, 0.1])
    got = P.loo_lpd(units, ("f",))
    n = sum(r.size for r, _ in units)
    A = sum(c["f"].T @ c["f"] for _, c in units)
    Lam = A / n + 1e-12 * np.trace(A) / 3 * np.eye(3)
    for j, (r, c) in enumerate(units):
        Xo = [u[1]["f"] for i, u in enumerate(units) if i != j]
        ro = [u[0] for i, u in enumerate(units) if i != j]
        Vinv = sum(x.T @ x for x in Xo) + Lam
        m = np.linalg.solve(Vinv, sum(x.T @ y for x, y in zip(Xo, ro)))
        C = np.eye(r.size) + c["f"] @ np.linalg.solve(Vinv, c["f"].T)
        e = r - c["f"] @ m
        lp = -0.5 * (e @ np.linalg.solve(C, e) + np.linalg.slogdet(C)[1])
        assert got[j] == pytest.approx(lp + 0.5 * r @ r, rel=1e-6, abs=1e-6)


def test_a_shape_fitting_noise_does_not_predict():
    """No effect: a 3-column shape fitted on four units predicts the fifth worse than none, on
    average; a real shared effect predicts every held-out unit better."""
    rng = np.random.default_rng(2)
    null = np.concatenate([P.loo_lpd(_units(rng), ("f",)) for _ in range(40)])
    assert null.mean() < 0
    real = P.loo_lpd(_units(rng, beta=[0.5, 0.5, -0.5]), ("f",))
    assert np.all(real > 0) and real.mean() > 5


def _cw(r, Q=None):
    t = np.arange(r.size) / 8000.0
    data = SimpleNamespace(t=t, weight=np.ones(r.size), count=np.ones(r.size))
    return SimpleNamespace(r=r, Q=np.zeros((r.size, 0)) if Q is None else Q, data=data)


def test_noise_filter_whitens_coloured_vibration_and_keeps_white_noise():
    rng = np.random.default_rng(3)
    n = 1200
    white = rng.normal(size=n)
    f, (a, sd) = P._prewhiten(_cw(white))
    y = f(white)
    assert abs(np.std(y) - 1.0) < 0.1            # floored at the sensor's level: white stays white
    # a resonant AR(2) vibration (a mode at ~1.1 kHz at 8 kHz blocks) on top of the white noise
    v = np.zeros(n)
    e = rng.normal(size=n) * 2.0
    for i in range(2, n):
        v[i] = 1.2 * v[i - 1] - 0.8 * v[i - 2] + e[i]
    x = white + v
    f, (a, sd) = P._prewhiten(_cw(x))
    z = f(x)
    lag1 = np.corrcoef(z[:-1], z[1:])[0, 1]
    # whiter (the floor at the sensor level keeps the quiet band as it is, so not fully white)
    assert abs(np.corrcoef(x[:-1], x[1:])[0, 1]) > 0.5 and abs(lag1) < 0.3
    assert np.var(z) < 0.5 * np.var(x)           # the vibration's band is down-weighted, not counted


def test_sensor_zero_and_gain_are_nuisance(breaker):
    """A healthy capture read through a transducer zero of 2 mrad and a gain of +1 %: the sensor
    columns absorb them, the residual the hypotheses see stays at the noise floor."""
    from service.diagnosis.windows import prepare
    from tests.diagnosis.test_pipeline import _group

    caps = _group({}, "open", 1, 107)
    cap = caps[0]
    bent = replace(cap, travel=np.asarray(cap.travel) * 1.01 + 2e-3)
    w0 = prepare([cap], breaker, "open")
    w1 = prepare([bent], breaker, "open")
    chi0 = float(np.sum(w0.captures[0].project_out(w0.captures[0].r) ** 2))
    chi1 = float(np.sum(w1.captures[0].project_out(w1.captures[0].r) ** 2))
    n = w1.captures[0].r.size
    assert chi1 < n + 5 * np.sqrt(2 * n)
    assert chi1 < 1.2 * chi0 + 50
