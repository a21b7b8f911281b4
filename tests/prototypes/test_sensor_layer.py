"""The shared realistic sensor layer (service/prototypes/sensor.py): seeded, in its ranges, and
applicable to any prototype's capture."""

import numpy as np
import pytest

from drivers.capture import Capture
from service.prototypes import sensor

FS = 20_000.0


def _capture(stroke=1.0, n=4000, onset=0.02, dur=0.03):
    t = np.arange(n) / FS
    u = np.clip((t - onset) / dur, 0.0, 1.0)
    y = stroke * (3 * u ** 2 - 2 * u ** 3)           # a smooth stroke from rest to rest
    return Capture(travel=y, sample_rate=FS, source="synthetic")


def test_same_seed_same_unit_and_reading():
    cap = _capture()
    u1 = sensor.draw_unit(np.random.default_rng(7))
    u2 = sensor.draw_unit(np.random.default_rng(7))
    assert u1 == u2
    a = sensor.apply(cap, u1, np.random.default_rng(3), stroke=1.0)
    b = sensor.apply(cap, u2, np.random.default_rng(3), stroke=1.0)
    assert np.array_equal(a.travel, b.travel)
    c = sensor.apply(cap, u1, np.random.default_rng(4), stroke=1.0)
    assert not np.array_equal(a.travel, c.travel)          # the per-operation draws differ


def test_units_in_their_ranges():
    rng = np.random.default_rng(1)
    units = [sensor.draw_unit(rng) for _ in range(200)]
    assert all(abs(u.zero_rad) <= 2e-3 for u in units)
    assert all(abs(u.gain - 1.0) <= 0.01 for u in units)
    assert all(1 <= len(u.modes) <= 2 for u in units)
    assert all(300 <= f <= 1500 and 0.02 <= z <= 0.05 for u in units for f, z in u.modes)
    assert max(abs(u.zero_rad) for u in units) > 1.5e-3      # the range is used, not a constant


def test_zero_gain_and_bow_at_rest_and_end():
    cap = _capture()
    unit = sensor.SensorUnit(zero_rad=1e-3, gain=1.01, bow=0.003, skew=0.0, modes=())
    out = sensor.apply(cap, unit, np.random.default_rng(0), stroke=1.0)
    z = out.meta["sensor"]["zero_rad"]
    assert abs(z - 1e-3) < 5 * 0.3e-3
    assert out.travel[0] == pytest.approx(z, abs=3e-5)                     # at rest: the zero alone
    assert out.travel[-1] == pytest.approx(1.01 + z, abs=3e-5)             # at the end: gain, no bow
    mid = int(np.argmin(np.abs(cap.travel - 0.5)))
    assert out.travel[mid] - (1.01 * cap.travel[mid] + z) == pytest.approx(1.01 * 0.003, abs=1e-4)


def test_modes_ring_at_their_frequency_after_the_strikes():
    cap = _capture()
    unit = sensor.SensorUnit(zero_rad=0.0, gain=1.0, bow=0.0, skew=0.0, modes=((800.0, 0.03),))
    out = sensor.apply(cap, unit, np.random.default_rng(0), stroke=1.0)
    d = out.travel - cap.travel - out.meta["sensor"]["zero_rad"]
    t_latch, t_impact = sensor.strikes(cap.travel, FS)
    assert 0.019 < t_latch < 0.025 and 0.045 < t_impact < 0.051
    assert np.max(np.abs(d[: int(t_latch * FS) - 2])) < 3e-5               # nothing before the latch
    after = d[int(t_impact * FS): int(t_impact * FS) + 1024]
    f = np.fft.rfftfreq(after.size, 1 / FS)[np.argmax(np.abs(np.fft.rfft(after)))]
    assert abs(f - 800.0) < 40.0
    amps = [s["amp_rad"] for s in out.meta["sensor"]["strikes"]]
    assert all(0.3e-3 <= abs(a) <= 1e-3 for a in amps)


def test_adc_quantises_and_clips():
    cap = _capture(stroke=1.4)
    unit = sensor.SensorUnit(zero_rad=0.0, gain=1.0, bow=0.0, skew=0.0, modes=(), bits=12, span=(-0.1, 1.2))
    out = sensor.apply(cap, unit, np.random.default_rng(0), stroke=1.4)
    step = 1.3 / (2 ** 12 - 1)
    k = (out.travel + 0.1) / step
    assert np.allclose(k, np.round(k), atol=1e-6)
    assert out.travel.max() == pytest.approx(1.2)
    assert out.meta["sensor"]["clipped"] > 0
    assert out.travel_limits == (-0.1, 1.2)


def test_applies_to_a_prototype_capture():
    from service.prototypes.a import groups as ga

    rng = np.random.default_rng(5)
    unit = ga.make_unit(rng, effects={})
    cap, _ = ga.simulate_capture(unit, "open", conditions=ga.draw_conditions(rng), rng=rng)
    su = sensor.draw_unit(np.random.default_rng(5))
    out = sensor.apply(cap, su, np.random.default_rng(6), operation="open")
    assert out.travel.shape == cap.travel.shape and np.all(np.isfinite(out.travel))
    assert not np.array_equal(out.travel, cap.travel)
    assert cap.meta.get("sensor") is None                # the input is not changed
