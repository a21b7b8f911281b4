"""Prototype C effects: realistic size at strength 1, documented direction and region; conditions."""

import numpy as np
import pytest

from service.prototypes.c import EFFECTS, OPERATIONS, OUTSIDE, REALISTIC, draw_conditions
from service.prototypes.c.capture import PRE_S, RANGES
from service.prototypes.c.effects import sensor_error

from .helpers import FS, delta, index, run

PAIRS = [(n, op) for n in EFFECTS for op in OPERATIONS[n]]


def test_catalogue_shape():
    assert len(EFFECTS) == 10 and OUTSIDE == ("sensor_lag", "latch_ramp")
    assert set(REALISTIC) == set(EFFECTS) | set(OUTSIDE)
    assert {OPERATIONS[n] for n in ("orifice_buffer", "puffer_gas")} == {("open",)}
    assert {OPERATIONS[n] for n in ("contact_wipe", "cam_friction")} == {("close",)}


@pytest.mark.parametrize("name,op", PAIRS)
def test_each_effect_has_a_realistic_size_and_nothing_before_release(name, op):
    """At strength 1: 2-25 mrad somewhere in the stroke (noise is 1.5 mrad); zero at rest before."""
    d, t0, _, _ = delta(op, name)
    stroke = np.abs(d[index(PRE_S):index(t0["t_end_of_stroke_s"])]).max()
    assert 2e-3 < stroke < 25e-3, f"{name}/{op}: {stroke * 1e3:.1f} mrad"
    if name != "sensor_nonlinearity":     # a transducer error is there at rest too (zero only at closed)
        assert np.abs(d[:index(PRE_S)]).max() < 1e-9


def test_strength_scales_the_effect():
    small = np.abs(delta("open", "viscous_friction", strength=0.5)[0]).max()
    full = np.abs(delta("open", "viscous_friction", strength=1.0)[0]).max()
    assert 0.4 < small / full < 0.6


def test_orifice_buffer_acts_only_in_the_buffer_and_adds_overtravel():
    d, t0, t1, _ = delta("open", "orifice_buffer")
    assert np.abs(d[:index(t0["t_buffer_engage_s"]) - 1]).max() < 1e-9
    assert run("open", "orifice_buffer")[0].max() > run("open")[0].max() + 2e-3


def test_puffer_gas_runs_ahead_early_and_lags_late():
    d, t0, _, _ = delta("open", "puffer_gas")
    i0, ie = index(PRE_S), index(t0["t_end_of_stroke_s"])
    assert d[i0 + int(0.4 * (ie - i0))] > 1e-3 and d[ie] < -2e-3


def test_rod_elasticity_rings_at_its_natural_frequency_after_buffer_engagement():
    d, t0, t1, unit = delta("open", "rod_elasticity")
    i = index(t1["t_buffer_engage_s"])
    seg = d[i:i + index(0.015)]
    seg = seg - np.polyval(np.polyfit(np.arange(seg.size), seg, 3), np.arange(seg.size))
    spec = np.abs(np.fft.rfft(seg * np.hanning(seg.size), 16 * seg.size))
    f = np.fft.rfftfreq(16 * seg.size, 1 / FS)[np.argmax(spec)]
    assert f == pytest.approx(unit.shapes["rod_elasticity"]["freq_hz"], rel=0.15)


def test_stribeck_breakaway_slows_the_start_of_opening():
    d, t0, _, _ = delta("open", "stribeck_friction")
    i0, ie = index(PRE_S), index(t0["t_end_of_stroke_s"])
    assert d[i0 + int(0.3 * (ie - i0))] < -1e-3


def test_viscous_friction_slows_both_operations_everywhere():
    d, t0, _, _ = delta("open", "viscous_friction")
    d = d[:index(t0["t_end_of_stroke_s"])]
    assert d.max() < 1e-4 and d.min() < -2e-3          # opening: travel lags (lower) up to the peak
    d, _, _, _ = delta("close", "viscous_friction")
    assert d.min() > -1e-4 and d.max() > 2e-3          # closing: travel lags (stays higher)


def test_spring_nonlinearity_direction_follows_its_sign():
    for seed in (0, 1):
        d, t0, _, unit = delta("open", "spring_nonlinearity", seed=seed)
        i0, ie = index(PRE_S), index(t0["t_end_of_stroke_s"])
        gamma = unit.shapes["spring_nonlinearity"]["gamma_opening"]
        assert np.sign(d[i0 + int(0.3 * (ie - i0))]) == np.sign(gamma)   # progressive: stronger when charged


@pytest.mark.parametrize("op", ["open", "close"])
def test_sensor_nonlinearity_is_its_reading_law_and_zero_at_closed(op):
    d, _, _, unit = delta(op, "sensor_nonlinearity")
    base = run(op)[0][:d.size]
    assert np.abs(d - sensor_error(base, 1.0, unit.shapes["sensor_nonlinearity"])).max() < 3e-5
    closed = np.abs(base) < 2.2e-5          # the closed position, to one 16-bit step
    assert closed.any() and np.abs(d[closed]).max() < 3e-5


def test_contact_wipe_acts_only_after_touch_and_slows_closing():
    d, _, _, unit = delta("close", "contact_wipe")
    base = run("close")[0][:d.size]
    before = base > unit.shapes["contact_wipe"]["wipe_rad"] + 0.02
    assert np.abs(d[before]).max() < 1e-9 and d.max() > 1e-3 and d.min() > -1e-4


def test_cam_friction_slows_closing():
    d, _, _, _ = delta("close", "cam_friction")
    assert d.min() > -1e-4 and d.max() > 2e-3


def test_outside_effects():
    d, t0, _, _ = delta("open", "sensor_lag")
    assert d.min() < -3e-3 and d[index(PRE_S):index(t0["t_end_of_stroke_s"]) - 200].max() < 1e-4
    _, t0, _ = run("open")
    _, t1, _ = run("open", "latch_ramp")
    assert t1["t_motion_s"] > t0["t_motion_s"] and t1["outside_catalogue"] and not t0["outside_catalogue"]


def test_more_buffer_damping_means_less_overtravel():
    soft = run("open", cond=(("buffer_damping", 0.85),))[0].max()
    hard = run("open", cond=(("buffer_damping", 1.2),))[0].max()
    assert hard < soft - 2e-3


def test_friction_and_spring_charge_change_the_opening_time():
    t_hi = run("open", cond=(("friction", 1.15),))[1]["t_end_of_stroke_s"]
    t_lo = run("open", cond=(("friction", 0.85),))[1]["t_end_of_stroke_s"]
    assert t_hi > t_lo
    strong = run("open", cond=(("spring_charge", 1.01),))[0]
    weak = run("open", cond=(("spring_charge", 0.99),))[0]
    assert strong[index(PRE_S + 0.02)] > weak[index(PRE_S + 0.02)] + 1e-3


def test_draw_conditions_ranges_and_temperature_link():
    rng = np.random.default_rng(7)
    draws = [draw_conditions(rng) for _ in range(300)]
    for key, (lo, hi) in RANGES.items():
        vals = np.array([d[key] for d in draws])
        assert vals.min() >= lo and vals.max() <= hi, key
    temp = np.array([d["temperature_c"] for d in draws])
    damp = np.array([d["buffer_damping"] for d in draws])
    assert np.corrcoef(temp, damp)[0, 1] < -0.9     # cold oil is thicker: more buffer damping
