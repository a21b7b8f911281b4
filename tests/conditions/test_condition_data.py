"""The dataset seam and the pure pieces of the condition studies (no fitting)."""

import numpy as np
import pytest

from service.studies.common import load_reference
from service.studies.condition_classifiers import NearestNominal
from service.studies.condition_data import (
    FEATURE_POINTS, DatasetSpec, bo_step, condition_breaker, make_capture, noise_for_snr, snr_db,
    travel_features)
from service.studies.conditions import deviations


def test_opening_step_raises_only_bo_by_about_150():
    base = load_reference()
    spec = DatasetSpec(operation="open")
    p0 = condition_breaker(base, spec, 0).design_parameters()
    p3 = condition_breaker(base, spec, 3).design_parameters()
    assert (p3["BO"] - p0["BO"]) / 3 == pytest.approx(bo_step(base), rel=1e-9)
    assert 145.0 < bo_step(base) < 155.0
    for name in ("AO", "DO", "EO"):
        assert p3[name] == pytest.approx(p0[name], rel=1e-12)


def test_closing_step_changes_geometry_not_parameters():
    base = load_reference()
    spec = DatasetSpec(operation="close")
    b0, b4 = condition_breaker(base, spec, 0), condition_breaker(base, spec, 4)
    assert b4.xC0 - b0.xC0 == pytest.approx(4 * 3.5e-3)
    for name in ("AC", "BC", "CC"):
        assert b4.design_parameters()[name] == pytest.approx(b0.design_parameters()[name], rel=1e-12)


def test_run_spread_stays_within_its_band():
    base = load_reference()
    spec = DatasetSpec(operation="open", friction_spread=0.02, damping_spread=0.03)
    rng = np.random.default_rng(3)
    runs = [condition_breaker(base, spec, 0, rng) for _ in range(200)]
    tof = np.array([r.TOf for r in runs]) / base.TOf - 1
    cb = np.array([r.cb for r in runs]) / base.cb - 1
    assert np.all(np.abs(tof) <= 0.02) and np.all(np.abs(cb) <= 0.03)
    assert tof.std() > 0.005  # the spread is really applied


def test_capture_is_reproducible_and_features_have_fixed_length():
    spec = DatasetSpec(operation="open", source="reduced")
    a, truth_a, _ = make_capture(spec, 1, 2)
    b, truth_b, _ = make_capture(spec, 1, 2)
    c, _, _ = make_capture(spec, 1, 3)
    assert np.array_equal(a.travel, b.travel) and truth_a == truth_b
    assert not np.array_equal(a.travel[: c.travel.size], c.travel[: a.travel.size])
    f = travel_features(a)
    assert f.shape == (FEATURE_POINTS,)
    # The window ends after the opening: the last features sit near the open position.
    assert f[-1] > 0.8


def test_snr_and_noise_are_inverse():
    spec = DatasetSpec(operation="open", source="reduced")
    assert snr_db(noise_for_snr(40.0, spec), spec) == pytest.approx(40.0)
    # The paper's 1.5 mrad sensor noise sits above the 50 dB end of the robustness range.
    assert snr_db(0.0015, spec) > 50.0


def test_nearest_nominal_normalises_units_and_rejects_failed_fits():
    rng = np.random.default_rng(0)
    y = np.repeat(np.arange(3), 30)
    # Column 0 separates the classes by 6 within-class sd; column 1 is pure noise 1000× larger.
    X = np.column_stack([y * 6.0 + rng.normal(0, 1, y.size), rng.normal(0, 1000, y.size)])
    clf = NearestNominal().fit(X, y)
    assert np.mean(clf.predict(X) == y) > 0.95
    assert clf.predict(np.array([[np.nan, 0.0]]))[0] == -1


def test_deviations_use_stepped_reference_for_bo():
    cond = np.repeat(np.arange(4), 5)
    bo = 5000.0 + 150.0 * cond
    ao = np.where(cond == 2, 3090.0, 3000.0)
    dev = deviations(np.column_stack([ao, bo]), cond, ["AO", "BO"], step={"BO": 150.0})
    assert dev["max_deviation"]["BO"] == pytest.approx(0.0, abs=1e-12)
    assert dev["max_deviation"]["AO"] == pytest.approx(67.5 / 3022.5)
    assert dev["slope"]["BO"] == pytest.approx(150.0)
