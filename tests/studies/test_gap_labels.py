"""The corpus's labels from the oracle alone (issue 48 item 1) and the second sensor kind."""

import numpy as np
import pytest

from service.studies.gap.labels import bow_delta_chi2, label, threshold


def _row(truth=(), outside=False, delta=0.0, twin=None, bow=None, failed=()):
    o = {"delta_chi2": delta, "failed_fits": list(failed)}
    if twin is not None:
        o["healthy_delta_chi2"] = twin
    return {"truth": list(truth), "outside": outside, "oracle": o, "bow_delta_chi2": bow}


def test_labels_follow_the_oracle():
    assert label(_row(["orifice_buffer"], delta=500.0))[0] == "orifice_buffer"
    assert label(_row(["orifice_buffer"], delta=50.0))[0] == "none"                 # undetectable
    assert label(_row(["puffer_gas", "orifice_buffer"], delta=900.0))[0] == "orifice_buffer+puffer_gas"
    assert label(_row(outside=True, delta=300.0))[0] == "unexplained"
    assert label(_row(outside=True, delta=30.0))[0] == "none"
    # the prototype's own gap: its healthy twin misses by itself (E: Δχ² ≈ 590,000)
    assert label(_row((), delta=590_000.0, twin=590_000.0))[0] == "unexplained"
    assert label(_row(["orifice_buffer"], delta=600_000.0, twin=590_000.0))[0] == "unexplained"
    # a failed oracle fit: no label, with the reason
    lab, why = label(_row(["orifice_buffer"], delta=1e9, failed=[2]))
    assert lab is None and "failed" in why


def test_the_threshold_is_the_none_tests_half_power_noncentrality_and_grows_with_the_group():
    from scipy.stats import chi2, ncx2

    from service.diagnosis.none_test import LEVEL

    small, _ = threshold({"none_test": {"df_gap": 90}})
    large, why = threshold({"none_test": {"df_gap": 150}})
    assert small < large < 100.0 and "df 150" in why
    assert ncx2.sf(chi2.isf(LEVEL, 150), 150, large) == pytest.approx(0.5, abs=1e-6)
    legacy, why = threshold({})
    assert legacy == 100.0 and "former" in why
    # a row with the test's df: a gap of 60 is detectable on 5 captures (df 150), not on a fixed 100
    row = _row(["orifice_buffer"], delta=60.0)
    assert label(row)[0] == "none"
    assert label(dict(row, none_test={"df_gap": 150}))[0] == "orifice_buffer"


def test_a_detectable_sensor_bow_is_part_of_the_truth():
    assert label(_row((), bow=5000.0))[0] == "sensor_nonlinearity"
    assert label(_row((), bow=50.0))[0] == "none"
    assert label(_row(["orifice_buffer"], delta=500.0, bow=5000.0))[0] == "orifice_buffer+sensor_nonlinearity"
    assert label(_row(["sensor_nonlinearity"], delta=500.0, bow=5000.0))[0] == "sensor_nonlinearity"
    # beside a pair (three effects: no hypothesis holds them) or outside the catalogue
    assert label(_row(["puffer_gas", "orifice_buffer"], delta=900.0, bow=5000.0))[0] == "unexplained"


def test_the_bow_test_sees_a_bow_and_not_a_gain():
    from service.prototypes import sensor

    fs = 20_000.0
    t = np.arange(2000) / fs
    clean = 1.0 * np.clip((t - 0.02) / 0.06, 0.0, 1.0) ** 2
    s = {"zero_rad": 1e-3, "gain": 1.01, "bow": 0.003, "skew": 0.2, "strikes": [], "stroke_rad": 1.0}
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 2e-4, clean.size)
    read = sensor.reading(clean, fs, s) + noise
    assert bow_delta_chi2([read], [clean], [fs], [s], sensor.reading) > 1000.0
    flat = dict(s, bow=0.0)                                      # zero and gain only: nothing to detect
    read = sensor.reading(clean, fs, flat) + noise
    assert abs(bow_delta_chi2([read], [clean], [fs], [flat], sensor.reading)) < 30.0


def test_the_crank_sensor_reads_reproducibly_through_its_coupling():

    from service.prototypes import sensor_crank as K

    fs = 50_000.0
    t = np.arange(5000) / fs
    y = np.clip((t - 0.02) / 0.05, 0.0, 1.0)
    import dataclasses

    @dataclasses.dataclass
    class Cap:
        travel: np.ndarray
        sample_rate: float
        meta: dict
        travel_limits: tuple = (0.0, 1.0)

    cap = Cap(y, fs, {})
    u = K.draw_unit(np.random.default_rng(5))
    a = K.apply(cap, u, np.random.default_rng(6), stroke=1.0)
    b = K.apply(cap, u, np.random.default_rng(6), stroke=1.0)
    assert np.array_equal(a.travel, b.travel) and a.meta["sensor"]["kind"] == "crank"
    s = a.meta["sensor"]
    # the crank's form is zero at both ends of the stroke and the only difference without the bow
    assert K.crank_form(np.array([0.0, 1.0]), s["theta0"], 1.0) == pytest.approx([0.0, 0.0], abs=1e-12)
    d = K.reading(y, fs, s) - K.reading(y, fs, s, with_bow=False)
    assert np.max(np.abs(d)) > 1e-4 and abs(d[0]) < 1e-12
    # the play: a steady ramp is read half the play behind
    ramp = np.linspace(0.0, 0.01, 1000)
    assert K.play(ramp, 1e-3)[-1] == pytest.approx(0.01 - 0.5e-3)
