"""Each effect of E changes the curve by a physically sensible amount at s = 1 and
nothing at s = 0."""
import numpy as np
import pytest

from service.prototypes.e import EFFECTS, OUTSIDE, OPERATIONS, model as M, sim, sensor as SN

FS = M.SAMPLE_RATE
T0 = 0.02
U = M.design_unit()
PAIRS = [(e, op) for e in EFFECTS + OUTSIDE for op in OPERATIONS[e]]
_BASE = {}


def run(op, effects, temperature=20.0):
    return sim.simulate(op, U, temperature, effects, T0)


def base(op):
    if op not in _BASE:
        _BASE[op] = run(op, {})
    return _BASE[op]


def recorded(op, effects):
    r = run(op, effects)
    return SN.reading(r["tau"], U, effects.get("sensor_nonlinearity", 0.0))


def test_interface():
    assert len(EFFECTS) == 10 and len(set(EFFECTS)) == 10
    assert OUTSIDE == ("spring_surge",)
    assert set(OPERATIONS) == set(EFFECTS) | set(OUTSIDE)
    assert OPERATIONS["cam_friction"] == ("close",) and OPERATIONS["contact_wipe"] == ("close",)
    assert OPERATIONS["orifice_buffer"] == ("open",) and OPERATIONS["puffer_gas"] == ("open",)


@pytest.mark.parametrize("effect,op", PAIRS)
def test_zero_strength_is_the_healthy_curve(effect, op):
    assert np.array_equal(recorded(op, {effect: 0.0}), recorded(op, {}))


# max |change| of the recorded travel at s = 1 [rad]: (lower, upper) bounds
BOUNDS = {
    "linkage_kinematics": (5e-3, 0.08), "orifice_buffer": (5e-3, 0.06),
    "puffer_gas": (0.01, 0.10), "rod_elasticity": (5e-4, 0.02),
    "stribeck_friction": (5e-4, 0.05), "viscous_friction": (5e-3, 0.06),
    "spring_nonlinearity": (1e-3, 0.03), "sensor_nonlinearity": (1e-3, 0.006),
    "cam_friction": (0.01, 0.1), "contact_wipe": (3e-4, 0.01), "spring_surge": (3e-3, 0.05),
}


@pytest.mark.parametrize("effect,op", PAIRS)
def test_unit_strength_changes_the_curve_sensibly(effect, op):
    d1 = np.abs(recorded(op, {effect: 1.0}) - recorded(op, {}))
    lo, hi = BOUNDS[effect]
    assert np.all(np.isfinite(d1))
    assert lo < d1.max() < hi, (effect, op, d1.max())
    # before the motion starts nothing differs (except the sensor's own reading)
    if effect != "sensor_nonlinearity":
        assert d1[: int(T0 * FS)].max() == 0.0
    # over the valid interval (motion start to the end of the stroke) the change grows
    # with the strength
    b = base(op)["tau"]
    end = int(np.argmax(b)) if op == "open" else _t_end_close(b)
    sl = slice(int(T0 * FS), end + 1)
    d_small = np.abs(recorded(op, {effect: 0.5}) - recorded(op, {}))[sl].max()
    d_big = np.abs(recorded(op, {effect: 1.5}) - recorded(op, {}))[sl].max()
    assert d_small < d1[sl].max() < d_big


def _t_end_close(tau):
    return int(np.nonzero(tau <= tau.min() + 1e-9)[0][0])


def test_friction_effects_slow_the_motion():
    b = base("open")["tau"]
    i = int((T0 + 0.03) * FS)
    for e in ("viscous_friction", "stribeck_friction"):
        assert run("open", {e: 1.0})["tau"][i] < b[i]
    ib = _t_end_close(base("close")["tau"])
    for e in ("viscous_friction", "cam_friction", "stribeck_friction"):
        assert _t_end_close(run("close", {e: 1.0})["tau"]) > ib, e


def test_cold_grease_raises_viscous_friction():
    warm = np.abs(run("open", {"viscous_friction": 1.0}, 35.0)["tau"] - run("open", {}, 35.0)["tau"]).max()
    cold = np.abs(run("open", {"viscous_friction": 1.0}, -5.0)["tau"] - run("open", {}, -5.0)["tau"]).max()
    assert cold > 1.5 * warm


def test_orifice_buffer_acts_only_after_engagement():
    b = base("open")["tau"]
    o = run("open", {"orifice_buffer": 1.0})["tau"]
    pre = b < U.alpha0 - 1e-9
    assert np.array_equal(o[pre], b[pre])
    assert np.abs(o - b).max() > 5e-3


def test_puffer_pressure_builds_late_in_the_stroke():
    r = run("open", {"puffer_gas": 1.0})
    p = r["puffer_pa"] - r["puffer_pa"][0]
    i = int(np.argmax(p))
    assert 0.05e6 < p[i] < 0.3e6
    assert r["tau"][i] > 0.5  # the peak comes in the second half of the stroke
    b = base("open")["tau"]
    early = b < 0.2
    assert np.abs(r["tau"][early] - b[early]).max() < 0.1 * np.abs(r["tau"] - b).max()


def test_contact_wipe_acts_only_once_the_contacts_touch():
    r = run("close", {"contact_wipe": 1.0})
    b = base("close")
    before = b["x_contact"] > M.SCALE["arc_touch"] + 1e-4
    assert np.array_equal(r["tau"][before], b["tau"][before])
    assert _t_end_close(r["tau"]) > _t_end_close(b["tau"])


def test_linkage_keeps_the_stroke_and_varies_the_ratio():
    R = U.raec
    X, X1, X2 = sim.link(1.0, 1.0, R)
    assert X == pytest.approx(R, rel=1e-12)
    ratios = np.array([sim.link(t, 1.0, R)[1] for t in np.linspace(0, 1, 101)]) / R
    assert 0.8 < ratios.min() < 0.9 and 1.03 < ratios.max() < 1.1
    # X' is the derivative of X, X'' of X'
    t, e = 0.37, 1e-6
    assert (sim.link(t + e, 1.0, R)[0] - sim.link(t - e, 1.0, R)[0]) / (2 * e) == pytest.approx(sim.link(t, 1.0, R)[1], rel=1e-7)
    assert (sim.link(t + e, 1.0, R)[1] - sim.link(t - e, 1.0, R)[1]) / (2 * e) == pytest.approx(sim.link(t, 1.0, R)[2], rel=1e-5)


def test_rod_elasticity_stretches_the_rod_by_millimetres():
    r = run("open", {"rod_elasticity": 1.0})
    X = np.array([sim.link(t, 0.0, U.raec)[0] for t in r["tau"]])
    stretch = np.abs(X - r["x_contact"]).max()
    assert 2e-4 < stretch < 5e-3


def test_sensor_nonlinearity_leaves_the_motion_alone():
    r = run("open", {"sensor_nonlinearity": 1.0})
    assert np.array_equal(r["tau"], base("open")["tau"])
    d = np.abs(SN.reading(r["tau"], U, 1.0) - SN.reading(r["tau"], U, 0.0)).max()
    # 0.15 % of 150 mm = 0.225 mm at a ~100 mm lever: about 2-3 mrad
    assert 1.5e-3 < d < 4e-3


def test_spring_surge_rings_near_the_surge_frequency():
    b = base("open")["tau"]
    r = run("open", {"spring_surge": 1.0})["tau"]
    i0 = int(T0 * FS)
    d = (r - b)[i0: i0 + int(0.045 * FS)]
    d = d - np.polyval(np.polyfit(np.arange(d.size), d, 5), np.arange(d.size))
    spec = np.abs(np.fft.rfft(d * np.hanning(d.size), n=1 << 16))
    f = np.fft.rfftfreq(1 << 16, 1 / FS)
    fpk = f[np.argmax(spec * (f > 20))]
    assert 35.0 < fpk < 90.0  # first surge mode 0.5 sqrt(k/m) ~ 64 Hz, shifted by the crank
