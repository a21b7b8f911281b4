"""The dataset seam and the pure pieces of the condition studies (no fitting), and the field
nuisance of the Table 9 dataset (issue 22) at the quick size."""

import dataclasses

import numpy as np
import pytest

from service.studies.common import load_reference
from service.studies.classification_methods import FIELD_NUISANCE, UNIT_TOLERANCE, classification_spec
from service.studies.condition_classifiers import NearestNominal
from service.studies.condition_data import (
    FEATURE_POINTS, NUISANCE_NAMES, DatasetSpec, bo_step, condition_breaker, make_capture,
    noise_for_snr, snr_db, travel_features, unit_breaker, zero_on_idle)
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


# --- The field dataset of Table 9 (issue 22): each nuisance present and within its range -----



@pytest.fixture(scope="module")
def field_captures():
    """Every capture of the quick field set of both units, with its drawn nuisance."""
    out = {}
    for unit in (1, 2):
        spec = classification_spec(quick=True, unit=unit)
        out[unit] = [(c, i) + make_capture(spec, c, i, details=True)
                     for c in range(spec.conditions) for i in range(spec.per_condition)]
    return out


def _column(field_captures, name):
    return np.array([row[-1][name] for unit in field_captures for row in field_captures[unit]])


@pytest.mark.parametrize("name, lo, hi", [
    ("trigger_delay_s", *FIELD_NUISANCE["trigger_delay_s"]),
    ("offset_rad", -FIELD_NUISANCE["offset_rad"], FIELD_NUISANCE["offset_rad"]),
    ("gain", 1 - FIELD_NUISANCE["gain_spread"], 1 + FIELD_NUISANCE["gain_spread"]),
    ("friction_factor", 1 - FIELD_NUISANCE["friction_spread"], 1 + FIELD_NUISANCE["friction_spread"]),
    ("damping_factor", 1 - FIELD_NUISANCE["damping_spread"], 1 + FIELD_NUISANCE["damping_spread"]),
    ("snr_db", *FIELD_NUISANCE["snr_db_range"]),
])
def test_each_nuisance_is_drawn_within_its_range(field_captures, name, lo, hi):
    v = _column(field_captures, name)
    assert v.size == 36 and set(NUISANCE_NAMES) >= {name}
    assert np.all((v >= lo) & (v <= hi)), (name, v.min(), v.max())
    # Present: 36 uniform draws cover well over a third of the range.
    assert np.ptp(v) > 0.35 * (hi - lo), (name, np.ptp(v))


def test_trigger_offset_and_noise_are_in_the_recorded_travel(field_captures):
    for unit in field_captures:
        for c, i, cap, truth, breaker, nz in field_captures[unit]:
            fs = cap.sample_rate
            travel = np.asarray(cap.travel)
            n_idle = int(0.004 * fs)  # motion starts 5 ms or later
            idle = travel[:n_idle]
            # The sensor's zero offset is the idle level (to within the noise of the mean and one LSB).
            assert abs(np.median(idle) - nz["offset_rad"]) < 5 * nz["noise_rad"] / np.sqrt(n_idle) + 1e-4
            # The noise is the drawn SNR's (idle sd, quantisation adds < 1 %).
            assert np.std(idle, ddof=1) == pytest.approx(nz["noise_rad"], rel=0.15)
            # Motion (20 mrad clear of the idle level) starts after the drawn delay, not before.
            onset = np.argmax(travel - nz["offset_rad"] > 20e-3 + 5 * nz["noise_rad"]) / fs
            assert nz["trigger_delay_s"] <= onset < nz["trigger_delay_s"] + 0.006


def test_gain_and_friction_reach_the_capture():
    spec = classification_spec(quick=True, unit=1)
    cap, truth, _, nz = make_capture(spec, 1, 2, details=True)
    unity, truth0, _, nz0 = make_capture(dataclasses.replace(spec, gain_spread=0.0), 1, 2, details=True)
    assert nz0["gain"] == 1.0 and nz["gain"] != 1.0
    # Same draws otherwise: the recorded travel differs by the gain alone (end of the record).
    end = slice(-200, None)
    ratio = np.mean(cap.travel[end] - nz["offset_rad"]) / np.mean(unity.travel[end] - nz0["offset_rad"])
    assert ratio == pytest.approx(nz["gain"], abs=2e-3)
    # The friction draw is the simulator's: BO = (kO·xO1·rO − f·TOf)/J2.
    base = load_reference()
    b = condition_breaker(base, spec, 1)
    expected_bo = (b.kO * b.xO1 * b.rO - nz["friction_factor"] * b.TOf) / b.J2
    assert truth["BO"] == pytest.approx(expected_bo, rel=1e-9)


def test_second_unit_is_within_tolerance_and_the_fit_sees_only_the_design():
    base = load_reference()
    spec2 = classification_spec(quick=True, unit=2)
    u2 = unit_breaker(base, spec2)
    tol = UNIT_TOLERANCE["tolerance"]
    for name in ("kO", "J2", "cb"):
        ratio = getattr(u2, name) / getattr(base, name)
        assert abs(ratio - 1) <= tol and ratio != 1.0, name
    assert 0 < abs(u2.alpha0 - base.alpha0) <= UNIT_TOLERANCE["alpha0_tolerance_rad"]
    assert unit_breaker(base, classification_spec(quick=True, unit=1)) is base
    cap, truth, breaker, _ = make_capture(spec2, 0, 0, details=True)
    # The simulated truth is unit 2's; the breaker handed to the fit is the design's.
    assert truth["AO"] == pytest.approx(u2.kO * u2.rO**2 / u2.J2, rel=1e-9)
    assert breaker.kO == base.kO and breaker.J2 == base.J2 and breaker.alpha0 == base.alpha0


def test_zero_on_idle_removes_the_sensor_offset():
    spec = classification_spec(quick=True, unit=1)
    cap, _, breaker, nz = make_capture(spec, 0, 1, details=True)
    assert abs(nz["offset_rad"]) > 1e-3
    zeroed = zero_on_idle(cap, breaker, "open")
    assert abs(np.median(zeroed.travel[: int(0.004 * cap.sample_rate)])) < 3e-4


def test_clean_spec_keeps_the_aligned_trigger_of_the_conditions_study():
    spec = DatasetSpec(operation="open", source="reduced")
    assert not spec.field_nuisance
    _, _, _, nz = make_capture(spec, 0, 0, details=True)
    assert nz["trigger_delay_s"] == 0.02 and nz["offset_rad"] == 0.0 and nz["gain"] == 1.0
