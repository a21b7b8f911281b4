"""E with the design unit and every effect off reduces to the paper's reduced models
(Yan et al. 2026, Eq. 11 opening, Eq. 7 closing) with the reference breaker's parameters.
The reference solution is scipy's DOP853 at tight tolerances on the paper's equations,
written here from the reference files (the shared-data lane's ``../shared/reference``),
independently of E's code."""
import csv
import math
from pathlib import Path

import tomllib

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from service.prototypes.e import model as M, sim, sensor as SN

FS = 128_000.0
T0 = 0.02 + 3.3e-6  # motion start between two samples


@pytest.fixture(scope="module")
def ref(samples_dir) -> Path:
    """The shared reference folder beside the samples (the shared-data lane)."""
    d = samples_dir.parent / "reference"
    if not (d / "reference-252kV.toml").exists() or not (d / "cam-profile.csv").exists():
        pytest.skip(f"the shared reference breaker is not at {d}")
    return d


def _ref_params(ref: Path) -> dict:
    t = tomllib.loads((ref / "reference-252kV.toml").read_text())
    c, o, a, b = t["closing_spring"], t["opening_spring"], t["arc_chamber"], t["buffer"]
    return dict(c, **o, **a, **b)


def _paper(raw):
    J2 = raw["J2"]
    return dict(
        AO=raw["kO"] * raw["rO"] ** 2 / J2, BO=(raw["kO"] * raw["xO1"] * raw["rO"] - raw["TOf"]) / J2,
        CO=raw["caec"] * raw["raec"] ** 2 / J2, DO=raw["cb"] * raw["rb"] ** 2 / J2,
        EO=raw["kb"] * raw["rb"] ** 2 / J2, AC=raw["kC"] * raw["rC"] * raw["d"] / raw["J1"],
        BC=J2 / raw["J1"], CC=(raw["TCf"] + raw["kO"] * raw["xO0"] * raw["rO"]) / J2,
        DC=raw["kO"] * raw["rO"] ** 2 / J2, alpha0=raw["alpha0"],
    )


def test_design_constants_match_reference_file(ref):
    raw = _ref_params(ref)
    for k, v in M.REFERENCE.items():
        assert raw[k] == pytest.approx(v, rel=1e-12), k
    p = _paper(raw)
    r = M.reduced_parameters(M.design_unit(), 20.0)
    for k in ("AO", "BO", "CO", "DO", "EO", "AC", "BC", "CC", "DC"):
        assert r[k] == pytest.approx(p[k], rel=1e-12), k
    assert p["AO"] == pytest.approx(3423.9, abs=0.1) and p["AC"] == pytest.approx(23627, abs=1)


def _opening_reference(p, t_end):
    A, B, C, D, E, a0 = p["AO"], p["BO"], p["CO"], p["DO"], p["EO"], p["alpha0"]

    def f1(t, y):
        return [y[1], -A * y[0] + B - C * y[1]]

    def f2(t, y):
        return [y[1], -A * y[0] + B - C * y[1] - D * y[1] - E * (y[0] - a0)]

    ev = lambda t, y: y[0] - a0
    ev.terminal = True
    ev.direction = 1
    kw = dict(method="DOP853", rtol=1e-12, atol=1e-13, dense_output=True)
    s1 = solve_ivp(f1, (T0, t_end), [0.0, 0.0], events=ev, **kw)
    te = s1.t_events[0][0]
    s2 = solve_ivp(f2, (te, t_end), s1.y_events[0][0], **kw)
    return lambda t: np.where(t < te, s1.sol(np.minimum(t, te))[0], s2.sol(np.maximum(t, te))[0])


def _cam_ref(ref: Path):
    with open(ref / "cam-profile.csv") as fh:
        rows = list(csv.reader(fh))[1:]
    x = np.array([float(r[0]) for r in rows]); y = np.array([float(r[1]) for r in rows])
    return CubicSpline(x, y, bc_type="clamped"), x[-1]


def _closing_reference(ref, p, th_start, t_end):
    h, xend = _cam_ref(ref)
    h1, h2 = h.derivative(1), h.derivative(2)
    AC, BC, CC, DC = p["AC"], p["BC"], p["CC"], p["DC"]
    raw = _ref_params(ref)
    xC0, rC, d = raw["xC0"], raw["rC"], raw["d"]

    def f(t, y):
        th, w = y
        hh = float(h(min(th, xend))); d1 = float(h1(th)) if th < xend else 0.0
        d2 = float(h2(th)) if th < xend else 0.0
        # paper Eq. 7: theta1'' = AC f - BC T12/J2 h',  T12/J2 = theta2'' + CC + DC theta2
        drive = AC * (xC0 - rC * (1 - math.cos(th))) / (d + rC * math.cos(th)) * math.sin(th)
        acc = (drive - BC * d1 * (d2 * w * w + CC + DC * hh)) / (1.0 + BC * d1 * d1)
        return [w, acc]

    ev = lambda t, y: y[0] - xend
    ev.terminal = True
    ev.direction = 1
    s = solve_ivp(f, (T0, t_end), [th_start, 0.0], method="DOP853", rtol=1e-12, atol=1e-13,
                  dense_output=True, events=ev, max_step=2e-4)
    return s, h


def test_opening_reduces_to_eq11(ref):
    p = _paper(_ref_params(ref))
    u = M.design_unit()
    r = sim.simulate("open", u, 20.0, {}, T0)
    tau = r["tau"]
    t = np.arange(tau.size) / FS
    imax = int(np.argmax(tau))
    assert 0.05 < t[imax] - T0 < 0.062  # opening of about 57 ms, as the shared samples
    ref = _opening_reference(p, t[imax] + 1e-3)
    sel = (t >= T0) & (t <= t[imax])
    err = np.max(np.abs(tau[sel] - ref(t[sel])))
    print(f"opening reduction error {err:.3e} rad")
    assert err < 1e-5
    assert np.all(tau[t < T0] == 0.0)
    # the noiseless reading of the design sensor is the shaft angle
    assert np.max(np.abs(SN.reading(tau, u, 0.0) - tau)) < 1e-12


def test_closing_reduces_to_eq7(ref):
    p = _paper(_ref_params(ref))
    u = M.design_unit()
    r = sim.simulate("close", u, 20.0, {}, T0)
    tau = r["tau"]
    t = np.arange(tau.size) / FS
    iend = int(np.nonzero(tau <= 1e-9)[0][0])
    assert 0.030 < t[iend] - T0 < 0.040  # closing of about 36 ms
    s, h = _closing_reference(ref, p, u.theta1_start, t[iend] + 5e-3)
    sel = (t >= T0) & (t <= t[iend])
    th_ref = s.sol(t[sel])[0]
    tau_ref = 1.0 - h(np.minimum(th_ref, 3.141592653589793))
    err = np.max(np.abs(tau[sel] - tau_ref))
    print(f"closing reduction error {err:.3e} rad")
    assert err < 1e-5
    assert np.all(tau[t < T0] == 1.0)
