"""Prototype C physics: integrator cross-check, the strength-0 limit, timing and truth params."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from service.prototypes.c import closing, make_unit, opening
from service.prototypes.c.capture import NOMINAL_CONDITIONS, PRE_S
from service.prototypes.c.mechanism import applied, cam, reduced_params

from .helpers import FS, index, run

SAMPLES = Path("/work/shared/samples")


def _rk4(f, y0, t_end, h):
    """Fixed-step classical RK4: the independent integrator for the cross-check."""
    n = int(math.ceil(t_end / h))
    ys = np.empty((n + 1, y0.size))
    ys[0], y, t = y0, y0.astype(float), 0.0
    for i in range(n):
        k1 = f(t, y)
        k2 = f(t + h / 2, y + h / 2 * k1)
        k3 = f(t + h / 2, y + h / 2 * k2)
        k4 = f(t + h, y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t += h
        ys[i + 1] = y
    return np.arange(n + 1) * h, ys


def _unit_model(op, effects):
    unit = make_unit(np.random.default_rng(5), effects=effects)
    c = applied(unit.constants, NOMINAL_CONDITIONS)
    s = dict(unit.effects)
    if op == "open":
        return opening.build(c, s, unit.shapes)
    return closing.ClosingModel(c=c, s=s, sh=unit.shapes)


# Bound: 20 µrad, 1/75 of the 1.5 mrad travel noise; RK4 at 3.9 µs steps is far tighter than that
# except across the buffer switch, where its local error is O(h * jump).
@pytest.mark.parametrize("effects", [None, {"rod_elasticity": 1.2, "puffer_gas": 1.0, "stribeck_friction": 1.0}])
def test_opening_matches_fixed_step_rk4(effects):
    model = _unit_model("open", effects)
    segs, ev = opening.integrate(model, 0.0)
    t, ys = _rk4(model.rhs, model.y0(), ev["peak"], 1.0 / (2 * FS))
    keep = t <= ev["peak"]
    ours = opening.sample(segs, t[keep], 0)
    assert np.abs(ours - ys[keep, 0]).max() < 2e-5


@pytest.mark.parametrize("effects", [None, {"rod_elasticity": 1.2, "contact_wipe": 1.0, "cam_friction": 1.0}])
def test_closing_matches_fixed_step_rk4(effects):
    model = _unit_model("close", effects)
    sol, t_end = closing.integrate(model)
    t, ys = _rk4(model.rhs, model.y0(), t_end - 1e-5, 1.0 / (2 * FS))
    keep = t <= t_end - 1e-5
    ours = closing.travel(model, sol, t_end, t[keep])
    theirs = 1.0 - cam().h(ys[keep, 0])
    assert np.abs(ours - theirs).max() < 2e-5


def _reduced_opening(p, alpha0, t):
    """The paper's reduced opening model (Eq. 8), written here independently, Radau."""
    def f(_, y):
        th, w = y
        a = -p["AO"] * th + p["BO"] - p["CO"] * w
        if th > alpha0:
            a -= p["DO"] * w + p["EO"] * (th - alpha0)
        return [w, a]
    return solve_ivp(f, (0, t[-1]), [0, 0], t_eval=t, method="Radau", rtol=1e-11, atol=1e-13,
                     max_step=1e-4).y[0]


def _reduced_closing(p, c, t):
    """The paper's reduced closing model (Eq. 12) in theta1, LSODA."""
    cm, dc = cam(), c["kO"] * c["rO"] ** 2 / c["J2"]

    def f(_, y):
        q, w = y
        g = (c["xC0"] - c["rC"] * (1 - math.cos(q))) / (c["d"] + c["rC"] * math.cos(q)) * math.sin(q)
        h0, h1, h2 = cm.eval3(q)      # the cam table's spline (data shared; the equations are not)
        a = (p["AC"] * g - p["BC"] * h1 * (h2 * w * w + p["CC"] + dc * h0)) / (1 + p["BC"] * h1 ** 2)
        return [w, a]
    q = solve_ivp(f, (0, t[-1]), [c["theta1_start"], 0], t_eval=t, method="LSODA", rtol=1e-11, atol=1e-13,
                  max_step=1e-4).y[0]
    return 1.0 - cm.h(q)


COND = (("friction", 1.1), ("buffer_damping", 0.9), ("puffer", 1.05), ("spring_charge", 1.006))


def test_strength_zero_is_the_reduced_opening_with_truth_params():
    travel, truth, _ = run("open", None, seed=3, tolerance=0.03, cond=COND)
    i0, ie = index(PRE_S), index(truth["t_end_of_stroke_s"])
    t = np.arange(ie - i0) / FS
    red = _reduced_opening(truth["params"], truth["applied_constants"]["alpha0"], t)
    assert np.abs(travel[i0:ie] - red).max() < 5e-5     # 16-bit step is 21 µrad


def test_strength_zero_is_the_reduced_closing_with_truth_params():
    travel, truth, _ = run("close", None, seed=3, tolerance=0.03, cond=COND)
    i0, ie = index(PRE_S), index(truth["t_end_of_stroke_s"])
    t = np.arange(ie - i0) / FS
    red = _reduced_closing(truth["params"], truth["applied_constants"], t)
    assert np.abs(travel[i0:ie] - red).max() < 5e-5


def test_truth_params_of_the_design_unit_are_the_reference_values():
    _, t_open, _ = run("open", None, seed=0)
    _, t_close, _ = run("close", None, seed=0)
    ref = {"AO": 3423.9, "BO": 4806.6, "CO": 92.59, "DO": 39.51, "EO": 3950.6, "AC": 23627, "BC": 2.558,
           "CC": 10436}
    for k, v in {**t_open["params"], **t_close["params"]}.items():
        assert v == pytest.approx(ref[k], rel=2e-4), k


def test_truth_params_follow_the_conditions():
    _, t1, _ = run("open", None, seed=2, tolerance=0.03)
    _, t2, _ = run("open", None, seed=2, tolerance=0.03, cond=COND)
    c = t2["constants"]
    assert t2["params"]["DO"] == pytest.approx(0.9 * t1["params"]["DO"], rel=1e-12)
    assert t2["params"]["CO"] == pytest.approx(1.05 * t1["params"]["CO"], rel=1e-12)
    xo1 = c["xO0"] * 1.006 + c["rO"]
    assert t2["params"]["BO"] == pytest.approx((c["kO"] * xo1 * c["rO"] - 1.1 * c["TOf"]) / c["J2"], rel=1e-12)
    assert t2["params"] == reduced_params(t2["applied_constants"], "open")


def test_timing_and_stroke_are_the_breakers():
    """Energy/timing sanity against the shared independent sample (57 ms to peak, 1.057 rad)."""
    travel, truth, _ = run("open", None, seed=0)
    assert truth["t_end_of_stroke_s"] - truth["t_motion_s"] == pytest.approx(0.0567, abs=0.0015)
    assert 1.0 < travel.max() < 1.1
    assert truth["t_motion_s"] - truth["t_shock_s"] == pytest.approx(0.0004)
    ctravel, ctruth, _ = run("close", None, seed=0)
    assert ctruth["t_end_of_stroke_s"] - ctruth["t_motion_s"] == pytest.approx(0.0357, abs=0.0015)
    assert abs(ctravel[-1]) < 1e-4 and abs(ctravel[0] - 1.0) < 1e-4
    # ~20 ms rest before, ~30 ms after the end of stroke
    assert travel.size / FS == pytest.approx(truth["t_end_of_stroke_s"] + 0.030, abs=1e-4)


@pytest.mark.skipif(not (SAMPLES / "open-nominal.cfg").exists(), reason="shared samples not present")
@pytest.mark.parametrize("stem,op", [("open-nominal", "open"), ("close-nominal", "close")])
def test_effect_free_design_unit_reproduces_the_independent_sample(stem, op):
    """The shared sample follows the reduced model + 1.5 mrad noise: our residual must be the noise."""
    cfg = (SAMPLES / f"{stem}.cfg").read_text().splitlines()
    a, b = (float(x) for x in cfg[2].split(",")[5:7])
    rec = np.fromfile(SAMPLES / f"{stem}.dat", dtype=[("n", "<u4"), ("t", "<u4"), ("a0", "<i2"), ("a1", "<i2")])
    sample = rec["a0"] * a + b
    t_max = json.loads((SAMPLES / f"{stem}.truth.json").read_text())["t_max"]
    travel, _, _ = run(op, None, seed=0)
    i0, ie = index(PRE_S), index(t_max)
    rms = np.sqrt(np.mean((sample[i0:ie] - travel[i0:ie]) ** 2))
    assert rms < 1.6e-3
