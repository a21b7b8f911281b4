"""All effects off: the prototype is the reduced model (Eq. 11 closed form, Eq. 7 RK4)."""

import numpy as np
import pytest

from drivers.synthetic import synthesize_capture
from service.mechanics.closing import simulate_closing
from service.mechanics.opening import simulate_opening
from service.prototypes.a import (EFFECT_NAMES, OPERATIONS, REALISTIC, Effects,
                                         make_prototype_simulator, simulate_prototype_closing,
                                         simulate_prototype_opening)


@pytest.mark.parametrize("method", ["exact", "fast"])
def test_opening_off_is_eq11(breaker, params, t_grid, method):
    ref = simulate_opening(params, t_grid, CO=breaker.CO, alpha0=breaker.alpha0)
    got = simulate_prototype_opening(params, t_grid, breaker=breaker, method=method)
    assert got.success
    assert np.max(np.abs(got.theta - ref.theta)) < 1e-6
    assert abs(got.t_peak - ref.t_peak) < 1e-6
    assert abs(got.events["buffer_engaged"] - ref.events["buffer_engaged"]) < 1e-6


@pytest.mark.parametrize("method", ["exact", "fast"])
def test_closing_off_is_eq7(breaker, params, t_grid, method):
    ref = simulate_closing(params, t_grid, cam=breaker.cam, geometry=breaker.closing_geometry)
    got = simulate_prototype_closing(params, t_grid, breaker=breaker, method=method)
    assert got.success
    valid = t_grid <= ref.t_peak
    assert np.max(np.abs(got.theta - ref.theta)[valid]) < 1e-6
    assert abs(got.t_peak - ref.t_peak) < 1e-6


def test_opening_off_other_parameters(breaker, t_grid):
    p = {"AO": 2500.0, "BO": 5500.0, "DO": 20.0, "EO": 5000.0}
    ref = simulate_opening(p, t_grid, CO=breaker.CO, alpha0=breaker.alpha0)
    got = simulate_prototype_opening(p, t_grid, breaker=breaker, method="fast")
    assert np.max(np.abs(got.theta - ref.theta)) < 1e-6


CASES = [(n, op) for n in EFFECT_NAMES for op in OPERATIONS[n]]


@pytest.mark.parametrize("name,op", CASES)
def test_fast_matches_exact(breaker, params, t_grid, name, op):
    """The compiled RK4 used by the fits agrees with the scipy reference on every effect."""
    eff = Effects.only(name, REALISTIC[name])
    exact = make_prototype_simulator(breaker, eff, op)(params, t_grid)
    fast = make_prototype_simulator(breaker, eff, op, method="fast")(params, t_grid)
    assert exact.success and fast.success
    valid = t_grid <= exact.t_peak
    assert np.max(np.abs(exact.theta - fast.theta)[valid]) < 2e-5
    assert abs(exact.t_peak - fast.t_peak) < 2e-5


def test_cam_friction_is_exactly_bc_over_eta(breaker, params, t_grid):
    """Cam loss η is the rescaling BC -> BC/η (docs: absorbed, no residual)."""
    loss = 0.08
    got = simulate_prototype_closing(params, t_grid, breaker=breaker,
                                     effects=Effects(cam_friction=loss), method="fast")
    p2 = dict(params, BC=params["BC"] / (1 - loss))
    ref = simulate_closing(p2, t_grid, cam=breaker.cam, geometry=breaker.closing_geometry)
    assert got.success and ref.success
    valid = t_grid <= ref.t_peak
    assert np.max(np.abs(got.theta - ref.theta)[valid]) < 1e-6


def test_simulator_feeds_synthesize_capture(breaker, params):
    sim = make_prototype_simulator(breaker, Effects(orifice_buffer=0.6), "open", method="fast")
    cap, truth = synthesize_capture(breaker, "open", params, rng=np.random.default_rng(3), simulate=sim)
    base, _ = synthesize_capture(breaker, "open", params, rng=np.random.default_rng(3))
    assert cap.travel.size != base.travel.size or np.max(np.abs(cap.travel - base.travel)) > 0.01
    assert truth.t_peak > truth.t_motion


def test_bad_effects_are_refused(breaker):
    with pytest.raises(ValueError, match="cam_friction"):
        make_prototype_simulator(breaker, Effects(cam_friction=0.1), "open")
    with pytest.raises(ValueError, match=">= 0"):
        Effects(viscous_friction=-1.0)
    with pytest.raises(ValueError, match="unknown effect"):
        Effects.only("magic", 1.0)
    with pytest.raises(ValueError, match="below 1"):
        Effects(cam_friction=1.0)
