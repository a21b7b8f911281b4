"""Each effect on: energy balance (independent formulas written here from the docstrings),
sign, and the phase of the motion where it acts."""

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from service.mechanics.closing import simulate_closing
from service.mechanics.opening import simulate_opening
from service.prototypes.a import (REALISTIC, Effects, make_prototype_simulator,
                                         prototype_state, simulate_prototype_opening)

MU, ZETA, F_REF = 0.35, 0.05, 150.0


def _rod(eps):
    w = 2 * np.pi * F_REF / np.sqrt(eps)
    return w * w * MU * (1 - MU), 2 * ZETA * w * MU * (1 - MU)


def _gas(phi, pi_g, BO, stroke):
    tv = 1.6 * stroke
    p = (1 - np.minimum(np.maximum(phi, 0), 0.95 * tv) / tv) ** -1.4 - 1
    return pi_g * BO * p / ((1 - 1 / 1.6) ** -1.4 - 1)


OPEN_EFFECTS = ["linkage_kinematics", "orifice_buffer", "puffer_gas", "rod_elasticity",
                "stribeck_friction", "viscous_friction", "spring_nonlinearity"]


@pytest.mark.parametrize("name", OPEN_EFFECTS)
def test_opening_energy_balance(breaker, params, name):
    """Kinetic + stored energy = work of the springs − dissipation, along the whole stroke."""
    s = 2.0 * REALISTIC[name]  # stronger than realistic, so a wrong term would show
    eff = Effects.only(name, s)
    tr = simulate_prototype_opening(params, np.arange(0, 0.1, 1e-4), breaker=breaker, effects=eff)
    t = np.arange(0.0, tr.t_peak, 2e-6)
    th, om, ph, vp = prototype_state("open", params, t, breaker=breaker, effects=eff)
    AO, BO, DO, EO = (params[k] for k in ("AO", "BO", "DO", "EO"))
    CO, a0, X1, L = breaker.CO, breaker.alpha0, breaker.xO1 / breaker.rO, breaker.stroke
    beta = s if name == "spring_nonlinearity" else 0.0
    w_spring = -AO * th**2 / 2 + BO * th + beta * AO / X1 * (X1**3 - (X1 - th) ** 3) / 3
    w_buffer = -0.5 * EO * np.maximum(th - a0, 0) ** 2
    pi_g = s if name == "puffer_gas" else 0.0
    w_gas = -cumulative_trapezoid(_gas(ph, pi_g, BO, L), ph, initial=0.0)
    lam = s if name == "linkage_kinematics" else 0.0
    j = 1 - lam * np.sin(th - L / 2) ** 2
    engaged = th > a0
    power = DO * om**2 * engaged
    if name == "rod_elasticity":
        K, C = _rod(s)
        ke = 0.5 * (1 - MU) * om**2 + 0.5 * MU * vp**2 + 0.5 * K * (th - ph) ** 2
        power = power + CO * vp**2 + C * (om - vp) ** 2
    else:
        ke = 0.5 * j * om**2
        power = power + CO * j * om**2
    if name == "orifice_buffer":
        a = 1 - 0.5 * np.minimum((th - a0) / (L - a0), 1)
        power = power + engaged * s * DO * om * np.abs(om) / 20.0 / a**2 * om
    if name == "stribeck_friction":
        power = power + s * BO * np.exp(-(om / 2.0) ** 2) * np.tanh(om / 0.05) * om
    if name == "viscous_friction":
        power = power + s * CO * om**2
    dissipated = cumulative_trapezoid(power, t, initial=0.0)
    balance = w_spring + w_buffer + w_gas - dissipated - ke
    assert dissipated[-1] > 0
    assert np.max(np.abs(balance)) < 2e-4 * np.max(ke)


CLOSE_EFFECTS = ["linkage_kinematics", "rod_elasticity", "stribeck_friction", "viscous_friction",
                 "spring_nonlinearity", "contact_wipe"]


@pytest.mark.parametrize("name", CLOSE_EFFECTS)
def test_closing_energy_balance(breaker, params, name):
    """Per J1: ½θ1'² + ½BC·j·θ2'² (+ rod) = closing-spring work − loads − dissipation."""
    s = REALISTIC[name]
    eff = Effects.only(name, s)
    tr = make_prototype_simulator(breaker, eff, "close", method="fast")(params, np.arange(0, 0.1, 1e-4))
    t = np.arange(0.0, tr.t_peak, 2e-6)
    th1, om1, ph, vp = prototype_state("close", params, t, breaker=breaker, effects=eff)
    AC, BC, CC, DC = (params[k] for k in ("AC", "BC", "CC", "DC"))
    g = breaker.closing_geometry
    h, h1, _ = breaker.cam.evaluate(th1)
    om2 = h1 * om1
    xs = g.xC0 - g.rC * (1 - np.cos(th1))
    beta = s if name == "spring_nonlinearity" else 0.0
    drive = AC * xs * np.sin(th1) / (g.d + g.rC * np.cos(th1)) * (1 + beta * xs / g.xC0)
    w_spring = cumulative_trapezoid(drive, th1, initial=0.0)
    power = BC * (CC + DC * h) * om2
    h0, h_end = breaker.cam.theta2[0], breaker.cam.theta2.max()
    if name == "rod_elasticity":
        K, C = _rod(s)
        ke = 0.5 * om1**2 + 0.5 * BC * ((1 - MU) * om2**2 + MU * vp**2 + K * (h - ph) ** 2)
        power = power + BC * C * (om2 - vp) ** 2
    else:
        lam = s if name == "linkage_kinematics" else 0.0
        j = 1 - lam * np.sin(h - 0.5 * (h0 + h_end)) ** 2
        ke = 0.5 * om1**2 + 0.5 * BC * j * om2**2
    if name == "stribeck_friction":
        th = g.theta1_start
        g0 = (g.xC0 - g.rC * (1 - np.cos(th))) * np.sin(th) / (g.d + g.rC * np.cos(th))
        power = power + s * AC * g0 * np.exp(-(om1 / 2.0) ** 2) * np.tanh(om1 / 0.05) * om1
    if name == "viscous_friction":
        power = power + BC * s * breaker.CO * om2**2
    if name == "contact_wipe":
        tt = h0 + 0.7 * (h_end - h0)
        wipe = np.where(h >= tt, s * CC * (0.5 * np.tanh(om2 / 0.05) + 0.5 * (h - tt) / (h_end - tt)), 0.0)
        power = power + BC * wipe * om2
    balance = w_spring - cumulative_trapezoid(power, t, initial=0.0) - ke
    assert np.max(np.abs(balance)) < 2e-4 * np.max(ke)


def _pair(breaker, params, name, op, t, strength=None):
    eff = Effects.only(name, REALISTIC[name] if strength is None else strength)
    got = make_prototype_simulator(breaker, eff, op, method="fast")(params, t)
    if op == "open":
        ref = simulate_opening(params, t, CO=breaker.CO, alpha0=breaker.alpha0)
    else:
        ref = simulate_closing(params, t, cam=breaker.cam, geometry=breaker.closing_geometry)
    return got, ref


T = np.arange(0.0, 0.1, 1 / 64000)


@pytest.mark.parametrize("name", ["orifice_buffer", "puffer_gas", "stribeck_friction",
                                  "viscous_friction"])
def test_losses_slow_the_opening(breaker, params, name):
    got, ref = _pair(breaker, params, name, "open", T)
    before_peak = T < min(got.t_peak, ref.t_peak) - 2e-3
    d = got.theta[before_peak] - ref.theta[before_peak]
    assert np.all(d <= 1e-9)
    assert d.min() < -1e-3


@pytest.mark.parametrize("name", ["viscous_friction", "contact_wipe", "stribeck_friction"])
def test_losses_slow_the_closing(breaker, params, name):
    got, ref = _pair(breaker, params, name, "close", T)
    valid = T < ref.t_peak
    d = got.theta[valid] - ref.theta[valid]
    assert np.all(d <= 1e-6)  # the reference RK4 (1/64 kHz steps) differs by < 1e-6 rad
    assert d.min() < -1e-3


@pytest.mark.parametrize("op", ["open", "close"])
def test_progressive_spring_speeds_up(breaker, params, op):
    got, ref = _pair(breaker, params, "spring_nonlinearity", op, T)
    assert got.t_peak < ref.t_peak
    early = T < 0.5 * ref.t_peak
    assert np.all(got.theta[early] - ref.theta[early] >= -1e-6)


def test_orifice_buffer_does_nothing_before_alpha0(breaker, params):
    got, ref = _pair(breaker, params, "orifice_buffer", "open", T)
    before = T < ref.events["buffer_engaged"]
    assert np.max(np.abs(got.theta[before] - ref.theta[before])) < 1e-7
    after = (T > ref.events["buffer_engaged"]) & (T < ref.t_peak)
    assert np.max(np.abs(got.theta[after] - ref.theta[after])) > 5e-3


def test_contact_wipe_does_nothing_before_touch(breaker, params):
    got, ref = _pair(breaker, params, "contact_wipe", "close", T)
    touch = got.events["contact_touch"]
    before = T < touch
    assert np.max(np.abs(got.theta[before] - ref.theta[before])) < 1e-7
    after = (T > touch) & (T < ref.t_peak)
    assert np.max(np.abs(got.theta[after] - ref.theta[after])) > 1e-3


def test_puffer_gas_acts_mid_to_late(breaker, params):
    got, ref = _pair(breaker, params, "puffer_gas", "open", T)
    d = np.abs(got.theta - ref.theta)
    early = T < np.interp(0.25, ref.theta[T < ref.t_peak], T[T < ref.t_peak])
    assert d[early].max() < 0.05 * d[T < ref.t_peak].max()


def test_stribeck_acts_at_the_start(breaker, params):
    """The speed deficit is built in the first milliseconds, then only carried along."""
    got, ref = _pair(breaker, params, "stribeck_friction", "open", T)
    dv = ref.omega - got.omega
    t_buf = ref.events["buffer_engaged"]
    start = T < 2e-3
    assert dv[start].max() > 0.5 * np.abs(dv[T < t_buf]).max()


def test_rod_rings_after_release(breaker, params):
    got, ref = _pair(breaker, params, "rod_elasticity", "open", T)
    dv = got.omega - ref.omega
    first = T < 0.015
    crossings = np.sum(np.diff(np.sign(dv[first][1:])) != 0)
    assert crossings >= 3  # an oscillation near f_rod, not a drift
    assert np.abs(dv[first]).max() > 0.1


def test_sensor_nonlinearity_changes_only_the_reading(breaker, params):
    eps = 0.01
    got, ref = _pair(breaker, params, "sensor_nonlinearity", "open", T, eps)
    u = ref.theta / breaker.stroke
    assert np.max(np.abs(got.theta - (ref.theta + eps * breaker.stroke * 4 * u * (1 - u)))) < 1e-7
    assert np.max(np.abs(got.omega - ref.omega)) < 1e-4


def test_linkage_acts_over_the_whole_stroke(breaker, params):
    got, ref = _pair(breaker, params, "linkage_kinematics", "open", T)
    # Less inertia away from mid-stroke: faster at the start, before the buffer.
    t_buf = ref.events["buffer_engaged"]
    early = (T > 1e-3) & (T < 0.5 * t_buf)
    assert np.all(got.theta[early] > ref.theta[early])
    late = (T > t_buf) & (T < ref.t_peak)
    assert np.max(np.abs(got.theta[late] - ref.theta[late])) > 1e-3
