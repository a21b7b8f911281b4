"""prototype D's vibration noise: silent before the first shock, coloured, growing with motion,
scaled as the unit's character says, and shared by the travel and vibration channels."""

from __future__ import annotations

import numpy as np
import pytest

from service.prototypes.d.noise import draw_noise, vibration_noise

FS = 128_000.0


@pytest.fixture
def case():
    t = np.arange(20_480) / FS
    # a bell of shaft speed from the latch at 20 ms to rest at 80 ms, peak 30 rad/s
    rate = np.where((t > 0.02) & (t < 0.08), 30 * np.sin(np.pi * (t - 0.02) / 0.06) ** 2, 0.0)
    character = draw_noise(np.random.default_rng(5))
    return t, rate, character, {"latch": 0.02, "buffer": 0.045, "end": 0.08}


def test_noise_follows_the_motion_and_is_coloured(case):
    t, rate, character, events = case
    travel, vibration, description = vibration_noise(np.random.default_rng(1), character, rate,
                                                     events, FS)
    assert np.all(travel[t < 0.02] == 0.0)  # nothing rings before the latch lets go
    moving = np.abs(rate) > 0.02 * np.abs(rate).max()
    rms = np.sqrt(np.mean(travel[moving] ** 2))
    assert rms == pytest.approx(character["coloured_rms_rad"], rel=1e-9)
    assert description["rms_rad"] == pytest.approx(rms, rel=1e-12)
    x = travel[moving]
    assert np.corrcoef(x[:-1], x[1:])[0, 1] > 0.9  # coloured, not white
    # the same excitation: the vibration channel's biggest shock is at the latch, at its peak
    k = int(np.argmax(np.abs(vibration)))
    assert 0.02 <= t[k] < 0.022
    assert abs(vibration[k]) == pytest.approx(character["latch_peak_g"], abs=3.0)
    assert np.abs(vibration[t < 0.02]).max() < 5 * 0.5  # only the accelerometer's floor


def test_noise_is_deterministic_for_its_generator(case):
    _, rate, character, events = case
    a = vibration_noise(np.random.default_rng(9), character, rate, events, FS)
    b = vibration_noise(np.random.default_rng(9), character, rate, events, FS)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
