"""Pieces of the diagnosis: the fit-grade integrator, phases and residual statistics."""

import numpy as np
import pytest

from service.diagnosis.data import FIT_DT
from service.diagnosis.phases import phase_bounds
from service.mechanics.opening import simulate_opening
from service.prototypes.a import REALISTIC, Effects, make_prototype_simulator, simulate_prototype_opening


@pytest.mark.parametrize("name", ["orifice_buffer", "rod_elasticity", "stribeck_friction"])
def test_fit_step_is_accurate_enough(breaker, name):
    """The diagnosis integrates at FIT_DT; against the exact reference it errs far below noise."""
    t = np.arange(0, 0.07, 1 / 8000)
    p = breaker.design_parameters()
    eff = Effects.only(name, REALISTIC[name])
    exact = make_prototype_simulator(breaker, eff, "open")(p, t)
    fast = simulate_prototype_opening(p, t, breaker=breaker, effects=eff, method="fast", dt_max=FIT_DT)
    valid = t < exact.t_peak
    assert np.max(np.abs(exact.theta - fast.theta)[valid]) < 1e-4  # noise floor 1.5e-3 rad


def test_opening_phases_split_at_alpha0(breaker):
    p = breaker.design_parameters()
    t = np.arange(0, 0.06, 1e-5)
    tr = simulate_opening(p, t, CO=breaker.CO, alpha0=breaker.alpha0)
    b = phase_bounds("open", t, tr.theta, tr.t_peak, breaker)
    assert [x[0] for x in b] == ["acceleration", "buffer_engagement", "buffer_stroke", "approach"]
    assert abs(b[0][2] - tr.events["buffer_engaged"]) < 2e-5
    assert b[-1][2] == pytest.approx(tr.t_peak)
    assert all(x[1] <= x[2] for x in b)


def test_cam_friction_is_absorbed_into_bc(breaker, make_capture):
    """Cam friction is exactly BC → BC/η: the identifiability check (projection + polish)
    finds it absorbed, with a BC bias of the sign and size of 1/η − 1 (+11 %; the closing's
    AC/BC/CC/τ are nearly degenerate, so the bias is only defined to a few per cent)."""
    from service.diagnosis.data import STATE, window_data
    from service.diagnosis.identifiability import absorption
    from service.estimation import fit_capture

    cap = make_capture(breaker, "close", seed=141)
    fr = fit_capture(cap, breaker, "close", seed=1)
    d = window_data(cap, fr, breaker, "close")
    x = np.array([fr.parameters[k] for k in STATE["close"]] + [fr.onset_delay_s])
    a = absorption("cam_friction", x, d, breaker, "close")
    assert not a["distinguishable"]
    assert a["residual_rad"] < 0.3 * d.noise
    assert 4 < a["parameter_shift"]["BC"] < 20


def test_cam_friction_is_absorbed_exactly_through_its_declared_equivalence(breaker):
    """cam_friction is BC -> BC/η: the absorption check must find a residual at noise level."""
    import numpy as np

    from service.diagnosis.identifiability import EXACT_EQUIVALENCE
    from service.mechanics.closing import simulate_closing
    from service.prototypes.a import REALISTIC, Effects, make_prototype_simulator

    p = breaker.design_parameters()
    s = REALISTIC["cam_friction"]
    t = np.arange(0, 0.05, 1 / 128000)
    proto = make_prototype_simulator(breaker, Effects(cam_friction=s), "close", method="exact")(p, t)
    x = np.array([p["AC"], p["BC"], p["CC"], 0.0])
    y = EXACT_EQUIVALENCE["cam_friction"](x, s, "close")
    reduced = simulate_closing(dict(p, AC=y[0], BC=y[1], CC=y[2]), t, cam=breaker.cam,
                               geometry=breaker.closing_geometry)
    assert np.max(np.abs(proto.theta - reduced.theta)) < 1e-5
