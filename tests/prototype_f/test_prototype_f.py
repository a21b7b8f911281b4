import json
import numpy as np
from scipy.integrate import solve_ivp
from service.prototypes.f import model as m
from service.prototypes.f.groups import write_groups


def _eq11(t, y, p):
    th, v = y
    a = p["BO"] - p["AO"] * th - p["CO"] * v
    if th >= p["alpha0"]:
        a -= p["DO"] * v + p["EO"] * (th - p["alpha0"])
    return [v, a]


def test_reduces_to_eq11():
    n = int(0.045 * m.FS)
    th = m.simulate(m.DESIGN, {}, n)
    t = np.arange(n) / m.FS
    ref = solve_ivp(_eq11, (0, t[-1]), [0, 0], t_eval=t, args=(m.DESIGN,), rtol=1e-10,
                    atol=1e-12, max_step=1e-5).y[0]
    assert np.abs(th - ref).max() < 1e-4


def test_effects_visible_at_1_not_0():
    th = m.simulate(m.DESIGN, {})
    for k in m.CATALOGUE + (m.OUTSIDE,):
        x = m.sensor(m.simulate(m.DESIGN, {k: 1.0}), {k: 1.0})
        assert np.abs(x - th).max() > 3 * 0.0015, k
        x0 = m.sensor(m.simulate(m.DESIGN, {k: 0.0}), {k: 0.0})
        assert np.abs(x0 - th).max() < 1e-12, k


def test_write_groups_deterministic(tmp_path):
    kw = dict(seed=3, per_effect=1, controls=1, two_effect=1, outside=1, captures_per_group=1)
    a = write_groups(tmp_path / "a", **kw)
    b = write_groups(tmp_path / "b", **kw)
    assert a == b
    assert json.loads((tmp_path / "a" / "manifest.json").read_text()) == a
    for g in a["groups"]:
        for s in g["stems"]:
            for suf in (".cfg", ".dat", ".clean.npy", ".healthy.npy"):
                assert (tmp_path / "a" / (s + suf)).read_bytes() == (tmp_path / "b" / (s + suf)).read_bytes()
