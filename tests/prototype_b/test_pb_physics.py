"""Prototype B physics: energy books, agreement with the reduced model, effect directions."""

import numpy as np
import pytest
from scipy.integrate import quad

from service.mechanics.closing import simulate_closing
from service.mechanics.opening import simulate_opening
from service.prototypes.b import EFFECTS, OPERATIONS
from service.prototypes.b.closing_dynamics import simulate_closing_b
from service.prototypes.b.dataset import reference_mechanism
from service.prototypes.b.effects import apply_effect, draw_shape
from service.prototypes.b.laws import Laws
from service.prototypes.b.mechanism import Effects
from service.prototypes.b.opening_dynamics import simulate_opening_b

FS = 128000.0
T_OPEN, T_CLOSE = 0.09, 0.06


@pytest.fixture(scope="module")
def mech():
    return reference_mechanism()


def _effects(effect, operation, strength=1.0, seed=3):
    shape = draw_shape(effect, operation, np.random.default_rng(seed))
    return apply_effect(Effects(), effect, strength, shape), shape


def _open(mech, eff, t_end=T_OPEN):
    t = np.arange(0.0, t_end, 1 / FS)
    return t, simulate_opening_b(mech, eff, t_end).sample(t)


def _close(mech, eff, t_end=T_CLOSE):
    t = np.arange(0.0, t_end, 1 / FS)
    motion = simulate_closing_b(mech, eff, t_end)
    return t, motion.sample(t), motion


CASES = [(None, "open"), (None, "close")] + [(e, op) for e in EFFECTS for op in OPERATIONS[e]]


@pytest.mark.parametrize("effect,operation", CASES)
def test_energy_balance(mech, effect, operation):
    """Spring energy released = kinetic + dissipated + stored (buffer, rod, fingers, gas work),
    to 1e-5 of the energy released, at every sample."""
    eff = _effects(effect, operation)[0] if effect else Effects()
    if operation == "open":
        _, o = _open(mech, eff)
        released = o["spring_released"]
        books = o["kinetic"] + o["stored"] + o["dissipated"] + o["gas_work"]
    else:
        _, o, motion = _close(mech, eff)
        cam = ~np.isnan(o["theta1"])
        # The closing spring's work, by quadrature of its torque law (independent of the ODE).
        laws = Laws(mech, eff)
        k = np.nonzero(cam)[0][-1]
        W = quad(laws.closing_spring_torque, mech.theta1_start, o["theta1"][k], limit=200)[0]
        assert o["spring_work"][k] == pytest.approx(W, rel=1e-6)
        released = o["spring_work"][cam]
        books = (o["kinetic"] + o["stored"] + o["dissipated"] + o["opening_spring_stored"])[cam]
    scale = np.max(np.abs(released))
    assert scale > 500.0  # the spring really did work [J]
    assert np.max(np.abs(released - books)) < 1e-5 * scale


def test_opening_agrees_with_reduced_model(mech, breaker):
    t, o = _open(mech, Effects())
    ref = simulate_opening(breaker.design_parameters(), t, CO=breaker.CO, alpha0=breaker.alpha0)
    valid = t <= ref.t_peak
    assert np.max(np.abs(o["travel"][valid] - ref.theta[valid])) < 1e-4
    assert np.max(np.abs(o["omega"][valid] - ref.omega[valid])) < 0.02


def test_closing_agrees_with_reduced_model(mech, breaker):
    t, o, motion = _close(mech, Effects())
    ref = simulate_closing(breaker.design_parameters(), t, cam=breaker.cam,
                           geometry=breaker.closing_geometry, dt_max=1 / 512000)
    valid = t <= ref.t_peak
    assert np.max(np.abs(o["theta2"][valid] - ref.theta[valid])) < 1e-4
    assert np.max(np.abs(o["travel"][valid] - (mech.stroke - ref.theta[valid]))) < 1e-4
    assert motion.events["latched"] == pytest.approx(ref.t_peak, abs=20e-6)


def test_orifice_buffer_forms_move_the_end_of_the_stroke_as_expected(mech):
    """Metering pin: more force late in the buffer, so less overtravel and a slower end;
    exponent > 1 (calibrated at the design speed) and free travel: a softer buffer at low speed."""
    _, base = _open(mech, Effects())
    _, meter = _open(mech, Effects(buffer_metering=0.3))
    _, expo = _open(mech, Effects(buffer_exponent=1.5))
    _, free = _open(mech, Effects(buffer_free=0.01))
    assert meter["travel"].max() < base["travel"].max() - 5e-3
    t = np.arange(base["theta"].size) / FS
    late = (base["theta"] > 0.9) & (meter["theta"] > 0.9) & (t < t[np.argmax(base["travel"] > base["travel"].max() - 0.01)])
    assert late.sum() > 100  # the late buffer phase, well before the stop
    assert np.all(meter["omega"][late] < base["omega"][late])
    assert expo["travel"].max() > base["travel"].max() + 5e-3
    assert free["travel"].max() > base["travel"].max() + 1e-3
    before = base["theta"] < mech.alpha0 - 1e-3
    assert np.max(np.abs(meter["travel"][before] - base["travel"][before])) < 1e-6


def test_puffer_gas_lowers_peak_speed_and_builds_pressure(mech):
    eff, _ = _effects("puffer_gas", "open")
    t, base = _open(mech, Effects())
    _, gas = _open(mech, eff)
    assert gas["omega"].max() < 0.99 * base["omega"].max()
    laws = Laws(mech, eff)
    k = np.searchsorted(t, 0.02)
    assert laws.gas_pressure(gas["contact"][k], gas["gas_mass"][k]) > 0.05
    assert gas["gas_mass"][k] < 1.0  # some gas has leaked through the nozzle


@pytest.mark.parametrize("operation", ["open", "close"])
def test_linkage_maps_travel_and_keeps_the_end_points(mech, operation):
    eff, _ = _effects("linkage_kinematics", operation)
    laws = Laws(mech, eff)
    theta = np.linspace(0.0, mech.stroke, 201)
    L = np.array([laws.linkage(v)[0] for v in theta])
    assert L[0] == pytest.approx(0.0, abs=1e-12) and L[-1] == pytest.approx(mech.stroke, abs=1e-12)
    assert np.max(np.abs(L - theta)) > 1e-3
    if operation == "open":
        _, o = _open(mech, eff)
        expected = np.array([laws.linkage(v)[0] for v in o["theta"]])
    else:
        _, o, _ = _close(mech, eff)
        expected = mech.stroke - np.array([mech.stroke - laws.linkage(mech.stroke - v)[0] for v in o["theta2"]])
    assert np.max(np.abs(o["travel"] - expected)) < 1e-9


@pytest.mark.parametrize("operation", ["open", "close"])
def test_rod_elasticity_oscillates_at_its_frequency(mech, operation):
    eff = Effects(rod_hz=200.0, rod_zeta=0.03, sensor_side="contact")
    if operation == "open":
        t, rigid = _open(mech, Effects(), 0.03)
        _, rod = _open(mech, eff, 0.03)
        window = rigid["theta"] < mech.alpha0 - 0.01
    else:
        t, rigid, _ = _close(mech, Effects(), 0.03)
        _, rod, _ = _close(mech, eff, 0.03)
        window = (rigid["theta2"] > 0.02) & (t < 0.03)
    d = rod["travel"][window] - rigid["travel"][window]
    d = d - np.polyval(np.polyfit(np.arange(d.size), d, 2), np.arange(d.size))
    assert np.max(np.abs(d)) > 5e-4
    spec = np.abs(np.fft.rfft(d * np.hanning(d.size), n=16 * d.size))
    f = np.fft.rfftfreq(16 * d.size, 1 / FS)
    f_peak = f[np.argmax(spec)]
    assert f_peak == pytest.approx(200.0 * np.sqrt(1 - 0.03**2), rel=0.1)


def _t_at(t, y, level):
    return t[np.argmax(y >= level)]


def test_stribeck_friction_delays_the_start(mech):
    eff, _ = _effects("stribeck_friction", "open")
    t, base = _open(mech, Effects())
    _, st = _open(mech, eff)
    assert _t_at(t, st["travel"], 0.2) > _t_at(t, base["travel"], 0.2)
    assert st["travel"].max() < base["travel"].max()


@pytest.mark.parametrize("effect", ["viscous_friction", "cam_friction", "contact_wipe", "stribeck_friction"])
def test_closing_losses_make_the_closing_later(mech, effect):
    eff, _ = _effects(effect, "close")
    t, base, mb = _close(mech, Effects())
    _, o, mo = _close(mech, eff)
    assert mo.events["latched"] > mb.events["latched"]
    if effect == "contact_wipe":
        assert mo.events["touch"] > 0.0
        after = (t > mo.events["touch"] + 1e-3) & (t < mb.events["latched"])
        assert np.all(o["travel"][after] >= base["travel"][after])


def test_viscous_friction_lowers_opening_speed(mech):
    eff, _ = _effects("viscous_friction", "open")
    _, base = _open(mech, Effects())
    _, o = _open(mech, eff)
    assert o["omega"].max() < 0.99 * base["omega"].max()


@pytest.mark.parametrize("gamma,faster", [(0.03, True), (-0.03, False)])
def test_spring_nonlinearity_direction(mech, gamma, faster):
    """Progressive (γ > 0) springs push harder than linear ones: faster opening and closing."""
    t, base = _open(mech, Effects())
    _, o = _open(mech, Effects(spring_gamma=gamma, spring_power=2, spring_which="opening"))
    assert (_t_at(t, o["travel"], 0.2) < _t_at(t, base["travel"], 0.2)) == faster
    _, _, mb = _close(mech, Effects())
    _, _, mc = _close(mech, Effects(spring_gamma=gamma, spring_power=1, spring_which="closing"))
    assert (mc.events["latched"] < mb.events["latched"]) == faster
