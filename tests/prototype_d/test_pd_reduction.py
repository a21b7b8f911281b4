"""With every effect off and the unit at design values, prototype D is the paper's reduced
models: opening Eq. 11 and closing Eqs. 2–7, written here again from the reorganised
parameters and integrated independently (scipy's solve_ivp, tight tolerances; the opening's
first phase also in closed form)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from service.prototypes.d.cam import cam_spline
from service.prototypes.d.groups import SAMPLES, simulate_capture
from service.prototypes.d.noise import draw_noise
from service.prototypes.d.simulate import SAMPLE_RATE_HZ, true_travel
from service.prototypes.d.unit import design, draw_unit, physical, reduced_truth

RELEASE_S = 0.02


@pytest.fixture(scope="module")
def constants():
    unit = design() | {"spring_sign": 1.0, "sensor_sign": 1.0}
    return physical(unit, {"temperature_C": 20.0, "damping_factor": 1.0})


def opening_reduced(p, alpha0, t):
    """Eq. 11 with solve_ivp: the buffer engages at θ = α0 (an event, so the solver steps
    across the switch exactly)."""
    def free(_, y):
        return [y[1], -p["AO"] * y[0] + p["BO"] - p["CO"] * y[1]]

    def buffered(_, y):
        return [y[1], -p["AO"] * y[0] + p["BO"] - p["CO"] * y[1] - p["DO"] * y[1]
                - p["EO"] * (y[0] - alpha0)]

    def engage(_, y):
        return y[0] - alpha0
    engage.terminal, engage.direction = True, 1
    kw = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-14}
    first = solve_ivp(free, (0, t[-1]), [0.0, 0.0], events=engage, dense_output=True, **kw)
    t_e = first.t_events[0][0]
    second = solve_ivp(buffered, (t_e, t[-1]), first.y_events[0][0], dense_output=True, **kw)
    return np.where(t < t_e, first.sol(np.minimum(t, t_e))[0], second.sol(np.maximum(t, t_e))[0]), t_e


def test_opening_reduces_to_eq11(constants):
    p = reduced_truth("open", constants)
    motion = true_travel("open", constants, {}, RELEASE_S, SAMPLES["open"])
    t = np.arange(SAMPLES["open"]) / SAMPLE_RATE_HZ
    after = t >= RELEASE_S
    ref, t_engage = opening_reduced(p, constants["alpha0"], t[after] - RELEASE_S)
    assert np.max(np.abs(motion.travel[after] - ref)) < 1e-6
    assert np.all(motion.travel[~after] == 0.0)
    # the first phase in closed form: θ* + e^(−CO t/2) (A cos ωd t + B sin ωd t)
    s = t[after] - RELEASE_S
    s = s[s < t_engage]
    theta_star = p["BO"] / p["AO"]
    wd = math.sqrt(p["AO"] - p["CO"] ** 2 / 4)
    a = -theta_star
    b = a * p["CO"] / (2 * wd)
    closed = theta_star + np.exp(-p["CO"] * s / 2) * (a * np.cos(wd * s) + b * np.sin(wd * s))
    assert np.max(np.abs(motion.travel[after][: s.size] - closed)) < 1e-6
    # and it is the reference breaker: the buffer engages ~25 ms after release
    assert 0.02 < t_engage < 0.03


def closing_reduced(p, c, t, phase=0.0):
    """Eqs. 2–7 in the reorganised form, θ1 the state, h from the cam spline directly:
    θ̈1 (1 + BC h′²) = AC (xC0 − rC(1 − cos θ1)) sin θ1/(d + rC cos θ1)
                      − BC h′ (h″ θ̇1² + CC + DC h)."""
    h = cam_spline()
    h1, h2 = h.derivative(1), h.derivative(2)

    def rhs(_, y):
        th1, w1 = y
        u = th1 - phase
        f = p["AC"] * (c["xC0"] - c["rC"] * (1 - math.cos(th1))) * math.sin(th1) / (
            c["d"] + c["rC"] * math.cos(th1))
        hp = float(h1(u))
        acc = (f - p["BC"] * hp * (float(h2(u)) * w1 ** 2 + p["CC"] + p["DC"] * float(h(u)))
               ) / (1 + p["BC"] * hp ** 2)
        return [w1, acc]
    sol = solve_ivp(rhs, (0, t[-1]), [c["theta1_start"], 0.0], method="DOP853", rtol=1e-12,
                    atol=1e-14, dense_output=True)
    return 1.0 - h(sol.sol(t)[0] - phase)


def test_closing_reduces_to_eqs_2_to_7(constants):
    p = reduced_truth("close", constants)
    motion = true_travel("close", constants, {}, RELEASE_S, SAMPLES["close"])
    t = np.arange(SAMPLES["close"]) / SAMPLE_RATE_HZ
    closed = motion.events_s["closed"]
    window = (t >= RELEASE_S) & (t <= closed)
    ref = closing_reduced(p, constants, t[window] - RELEASE_S)
    assert np.max(np.abs(motion.travel[window] - ref)) < 1e-6
    # the reference breaker closes in about 36 ms (reference-252kV.toml) and stays closed
    assert 0.030 < closed - RELEASE_S < 0.040
    assert np.all(np.abs(motion.travel[t > closed]) < 2e-4)
    held = motion.travel[t > closed + 0.05]
    assert np.ptp(held) < 1e-12  # the trip latch holds the shaft closed


@pytest.mark.parametrize("op", ["open", "close"])
def test_truths_give_the_reduced_curve_of_a_healthy_unit(op):
    """A drawn unit (tolerances, temperature, jitter) with no effect: the reduced model with the
    manifest's truth for that capture, read through the transducer's gain and zero, is the
    capture's clean travel."""
    rng = np.random.default_rng([7, 1])
    unit, noise = draw_unit(rng), draw_noise(rng)
    cap = simulate_capture(rng, op, unit, noise, {})
    truth = cap["truth"]
    t = np.arange(SAMPLES[op]) / SAMPLE_RATE_HZ
    delay = truth["trigger_delay_s"]
    if op == "open":
        after = t >= delay
        ref, _ = opening_reduced(truth, truth["alpha0_rad"], t[after] - delay)
    else:
        c = {"xC0": truth["xC0_m"], "rC": truth["rC_m"], "d": truth["d_m"],
             "theta1_start": truth["theta1_start_rad"]}
        closed = delay + 0.04  # well before the end of the stroke
        after = (t >= delay) & (t <= closed)
        ref = closing_reduced(truth, c, t[after] - delay, truth["cam_phase_rad"])
    expected = truth["sensor_offset_rad"] + truth["sensor_gain"] * ref
    assert np.max(np.abs(cap["clean"][after] - expected)) < 2e-6
