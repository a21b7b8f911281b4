"""The fit's residual split into what repeats from operation to operation (the model's bias) and
what varies (what the interval stands for): service/estimation/model_bias.py, and the transducer's
zero taken off before the fit (service/estimation/window.py). The coverage on repeated openings of
prototypes A–C through a realistic sensor is bench/interval_repeat.py's."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drivers.synthetic import synthesize_capture
from service.estimation import fit as fitmod
from service.estimation import fit_capture
from service.estimation.model_bias import (SHAPE_MEMORY, SHAPE_MIN_OPS, ResidualShape, bias_summary,
                                           repeating_rows, updated, varying_part)
from service.estimation.uncertainty import correlated_covariance, covariance
from service.estimation.warm_start import prior_from_design, prior_from_fit


def test_the_shape_survives_its_stored_form_and_a_damaged_one_is_none():
    s = ResidualShape("open", 0.001, 2.5e-4, (0.0, 1e-3, -2e-3), 4)
    assert ResidualShape.from_dict(s.to_dict()) == s
    assert ResidualShape.from_dict({}) is None
    assert ResidualShape.from_dict({**s.to_dict(), "values_rad": [1.0, float("nan")]}) is None
    assert ResidualShape.from_dict({**s.to_dict(), "dt_s": 0.0}) is None


def test_the_shape_is_the_running_mean_then_follows_with_its_memory():
    t = np.linspace(0.0, 0.05, 200)
    rng = np.random.default_rng(3)
    rows = [rng.normal(0, 1e-3, t.size) for _ in range(SHAPE_MEMORY)]
    shape = None
    for r in rows:
        shape = updated(shape, "open", t, r)
    assert shape.count == SHAPE_MEMORY
    np.testing.assert_allclose(shape.values_rad, np.mean(rows, axis=0), atol=1e-12)
    # past its memory, the newest operation weighs 1/SHAPE_MEMORY
    new = np.full(t.size, 1e-2)
    after = updated(shape, "open", t, new)
    np.testing.assert_allclose(after.values_rad, np.asarray(shape.values_rad) + (new - shape.values_rad) / SHAPE_MEMORY)
    # another operation's shape is not mixed in
    assert updated(shape, "close", t, new).count == 1


def test_the_smooth_misfit_is_split_from_the_rough_rest():
    t = np.linspace(0.0, 0.05, 220)
    w = np.full(t.size, np.sqrt(32.0))
    bump = 2e-3 * np.sin(np.pi * t / t[-1]) ** 2
    rough = np.random.default_rng(1).normal(0, 1e-3, t.size)
    varying, smooth = varying_part(w * (bump + rough), w, t)
    np.testing.assert_allclose(varying + smooth, w * (bump + rough), atol=1e-15)
    assert np.sqrt(np.mean((smooth / w - bump) ** 2)) < 0.25 * np.sqrt(np.mean(bump ** 2))
    assert np.sum(varying ** 2) > 0.9 * np.sum((w * rough) ** 2)
    # A window too short for the basis keeps everything as what varies.
    short = t[:20]
    v, sm = varying_part(w[:20] * rough[:20], w[:20], short)
    np.testing.assert_array_equal(v, w[:20] * rough[:20])
    np.testing.assert_array_equal(sm, 0.0)


def test_the_repeat_is_the_history_when_there_is_one_else_the_smooth_part():
    t = np.linspace(0.0, 0.05, 220)
    w = np.full(t.size, 2.0)
    values = tuple(1e-3 * np.cos(40 * t))
    shape = ResidualShape("open", float(t[0]), float(t[1] - t[0]), values, SHAPE_MIN_OPS)
    smooth = np.full(t.size, 7.0)
    rows, basis = repeating_rows(shape, smooth, w, t)
    np.testing.assert_allclose(rows, w * np.asarray(values), atol=1e-12)
    assert basis == f"mean residual of the breaker's last {SHAPE_MIN_OPS} operations"
    rows, basis = repeating_rows(dataclasses.replace(shape, count=SHAPE_MIN_OPS - 1), smooth, w, t)
    np.testing.assert_array_equal(rows, smooth)
    assert "smooth part" in basis


def test_the_bias_bound_is_the_misfit_along_each_parameter():
    t = np.linspace(0.0, 0.05, 220)
    w = np.ones(t.size)
    J = np.column_stack([np.ones_like(t), t])
    b = bias_summary(np.full(t.size, 1e-3), "a test", w, J, 1e-3, ["a", "b"])
    assert b["rms_rad"] == pytest.approx(1e-3) and b["rms_over_noise"] == pytest.approx(1.0)
    inv = np.linalg.inv(J.T @ J)
    norm = 1e-3 * np.sqrt(t.size)
    assert b["effect_bound"]["a"] == pytest.approx(norm * np.sqrt(inv[0, 0]), rel=1e-6)
    assert b["effect_bound"]["b"] == pytest.approx(norm * np.sqrt(inv[1, 1]), rel=1e-6)


@pytest.fixture(scope="module")
def clean_opening(breaker):
    cap, truth = synthesize_capture(breaker, "open", breaker.design_parameters(), rng=np.random.default_rng(11))
    return cap, truth


def test_the_zero_at_rest_is_taken_off_and_drawn_back(breaker, clean_opening):
    cap, truth = clean_opening
    base = fit_capture(cap, breaker, "open")
    moved = fit_capture(dataclasses.replace(cap, travel=cap.travel + 2e-3), breaker, "open")
    assert moved.zero_rad - base.zero_rad == pytest.approx(2e-3, abs=1e-5)
    for k, v in base.parameters.items():
        # a zero no longer leaks into the springs and the buffer
        assert moved.parameters[k] == pytest.approx(v, abs=0.05 * base.stderr[k]), k
    drawn = moved.fitted_travel(cap, breaker)
    assert drawn[:100].mean() == pytest.approx(moved.zero_rad, abs=1e-9)


def test_a_breaker_that_repeats_its_misfit_gets_the_interval_of_what_varies(breaker):
    """Openings that all carry the same smooth misfit (3 mrad peak, twice the noise): the interval
    leaves the misfit out, so it is narrower than the AR sandwich of the whole residual and never
    below the idle noise's; the misfit is the reported bias, from the breaker's own history once
    it has a few operations."""
    rng = np.random.default_rng(7)
    captures = []
    for _ in range(SHAPE_MIN_OPS + 2):
        cap, tr = synthesize_capture(breaker, "open", breaker.design_parameters(), rng=rng)
        t = np.arange(cap.travel.size) / cap.sample_rate
        u = np.clip((t - tr.t_motion) / (tr.t_peak - tr.t_motion), 0.0, 1.0)
        # two slow wiggles over the stroke: more than the four parameters can take up
        captures.append(dataclasses.replace(cap, travel=cap.travel + 3e-3 * np.sin(4 * np.pi * u) * np.sin(np.pi * u)))
    kept = {}
    real, real_varying = fitmod.correlated_covariance, fitmod.varying_part

    def keep(jac, resid, noise, scale, n_model=None, variance_factor=1.0):
        kept["full"] = real(jac, kept["resid"], noise, scale, n_model)
        kept["white"] = covariance(jac, noise, scale, n_model)
        return real(jac, resid, noise, scale, n_model, variance_factor)

    def keep_varying(resid, weight, t_rel):
        kept["resid"] = resid
        return real_varying(resid, weight, t_rel)

    prior, results = prior_from_design(breaker, "open"), []
    fitmod.correlated_covariance, fitmod.varying_part = keep, keep_varying
    try:
        for cap in captures:
            r = fit_capture(cap, breaker, "open", prior=prior)
            results.append((r, dict(kept)))
            prior = prior_from_fit(r.to_dict(), "the previous fit")
    finally:
        fitmod.correlated_covariance, fitmod.varying_part = real, real_varying
    first, _ = results[0]
    assert "smooth part" in first.model_bias["basis"]
    last, k = results[-1]
    assert last.model_bias["basis"] == f"mean residual of the breaker's last {len(captures) - 1} operations"
    assert last.model_bias["rms_over_noise"] > 0.3
    assert prior.residual_shape is not None and prior.residual_shape.count == len(captures)
    for r, kk in results:
        for i, n in enumerate(r.parameter_names[:-1]):
            assert kk["white"].stderr[i] <= r.stderr[n] * (1 + 1e-9), n
            assert r.stderr[n] < kk["full"].stderr[i], n
    assert correlated_covariance is real  # the module's own function is back
