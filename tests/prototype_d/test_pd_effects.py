"""Each of prototype D's effects changes the curve of the operation(s) it claims, and only
those; the sensor's effects leave the true motion alone; bad effects get clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from service.prototypes.d import EFFECTS, OPERATIONS, OUTSIDE
from service.prototypes.d.effects import SCALES, check_effects
from service.prototypes.d.groups import SAMPLES
from service.prototypes.d.simulate import sensor_reading, true_travel
from service.prototypes.d.unit import design, physical

RELEASE_S = 0.02
SENSOR = ("sensor_nonlinearity", "sensor_lag")
PAIRS = [(name, op) for name in EFFECTS + OUTSIDE for op in ("open", "close")]


@pytest.fixture(scope="module")
def setup():
    unit = design() | {"spring_sign": 1.0, "sensor_sign": 1.0}
    c = physical(unit, {"temperature_C": 20.0, "damping_factor": 1.0})
    base = {op: true_travel(op, c, {}, RELEASE_S, SAMPLES[op]) for op in ("open", "close")}
    return unit, c, base


def test_names_are_consistent():
    assert set(OPERATIONS) == set(EFFECTS) | set(OUTSIDE)
    assert set(SCALES) == set(OPERATIONS)
    assert not set(EFFECTS) & set(OUTSIDE)
    assert "pin_backlash" in OUTSIDE  # D's own invention, outside the catalogue


@pytest.mark.parametrize("name,op", PAIRS)
def test_effect_acts_where_it_claims(setup, name, op):
    unit, c, base = setup
    motion = true_travel(op, c, {name: 1.0}, RELEASE_S, SAMPLES[op])
    assert np.all(np.isfinite(motion.travel))
    reading = sensor_reading(motion.travel, unit, {name: 1.0})
    change = reading - sensor_reading(base[op].travel, unit, {})
    rms = float(np.sqrt(np.mean(change ** 2)))
    if op in OPERATIONS[name]:
        assert rms > 1e-4, f"{name} at s=1 changes the {op} reading by only {rms:.2e} rad"
        if name in SENSOR:
            np.testing.assert_array_equal(motion.travel, base[op].travel)
    else:
        assert rms == 0.0, f"{name} claims not to act on {op} but changes it by {rms:.2e} rad"


@pytest.mark.parametrize("name", ["orifice_buffer", "viscous_friction", "rod_elasticity", "puffer_gas"])
def test_strength_orders_the_change(setup, name):
    """A stronger effect moves the curve further (s = 0.5 vs 1.5)."""
    _unit, c, base = setup
    rms = [np.sqrt(np.mean((true_travel("open", c, {name: s}, RELEASE_S, SAMPLES["open"]).travel
                            - base["open"].travel) ** 2)) for s in (0.5, 1.5)]
    assert rms[1] > rms[0] > 0


@pytest.mark.parametrize("effects,op,words", [
    ({"blowby": 1.0}, "open", "unknown effect 'blowby'"),
    ({"cam_friction": 1.0}, "open", "acts on close, not on open"),
    ({"puffer_gas": -0.5}, "open", "finite number ≥ 0"),
    ({"puffer_gas": float("nan")}, "open", "finite number ≥ 0"),
    ({}, "trip", "operation must be 'open' or 'close'"),
])
def test_bad_effects_are_refused_in_words(effects, op, words):
    with pytest.raises(ValueError, match=words):
        check_effects(effects, op)
