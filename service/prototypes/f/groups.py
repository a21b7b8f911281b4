"""Prototype F capture groups: COMTRADE pairs + clean/healthy .npy + manifest.json."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from . import model as m

NOISE_RAD = 0.0015
N_TOTAL = int(round(m.DUR_S * m.FS))
N_PRE = int(round(m.PRE_S * m.FS))


def _unit(rng):
    return {k: (v * rng.uniform(0.97, 1.03) if k != "alpha0" else v) for k, v in m.DESIGN.items()}


def _conditions(unit, rng):
    """Per-capture: friction +-15 %, oil temperature -20..40 C, spring charge +-1 %."""
    fric = rng.uniform(0.85, 1.15)
    temp = rng.uniform(-20.0, 40.0)
    charge = rng.uniform(0.99, 1.01)
    p = dict(unit)
    f0 = m.FRICTION_DESIGN * unit["BO"] / m.DESIGN["BO"]
    spring = unit["BO"] + f0
    p["friction"] = f0 * fric
    p["BO"] = spring * charge - p["friction"]
    p["DO"] = unit["DO"] * math.exp(-0.012 * (temp - 20.0))   # oil viscosity with temperature
    return p, {"friction_factor": fric, "oil_temp_C": temp, "spring_charge": charge}


def _place(theta_motion):
    full = np.zeros(N_TOTAL)
    full[N_PRE:] = theta_motion[: N_TOTAL - N_PRE]
    return full


def _shock(t, t0, amp, f, tau):
    x = t - t0
    y = np.zeros_like(t)
    k = x >= 0
    y[k] = amp * np.sin(2 * np.pi * f * x[k]) * np.exp(-x[k] / tau)
    return y


def _vibration(theta_full, alpha0, rng):
    t = np.arange(N_TOTAL) / m.FS
    t0 = m.PRE_S
    v = _shock(t, t0 - m.LATCH_LEAD_S, 90.0 * rng.uniform(0.8, 1.2), 6200.0, 0.4e-3)
    i_a = np.argmax(theta_full >= alpha0)
    if theta_full[i_a] >= alpha0:
        v += _shock(t, t[i_a], 160.0 * rng.uniform(0.8, 1.2), 3400.0, 0.9e-3)
    i_p = int(np.argmax(theta_full))
    v += _shock(t, t[i_p], 320.0 * rng.uniform(0.8, 1.2), 2300.0, 1.6e-3)
    v += rng.normal(0.0, 2.0, N_TOTAL)
    return np.clip(v, -1000.0, 1000.0)


def write_comtrade(directory: Path, stem: str, travel: np.ndarray, vib: np.ndarray) -> None:
    """IEEE C37.111-2013 BINARY (int16): travel over 0..pi, vibration over +-1000 g."""
    a_t, b_t = math.pi / 65534.0, math.pi / 2.0
    a_v, b_v = 1000.0 / 32767.0, 0.0
    ct = np.clip(np.round((travel - b_t) / a_t), -32767, 32767).astype("<i2")
    cv = np.clip(np.round((vib - b_v) / a_v), -32767, 32767).astype("<i2")
    n = len(travel)
    cfg = "\r\n".join([
        "PROTO-F,hvcb-proto-f,2013", "2,2A,0D",
        f"1,travel,,,rad,{a_t:.9e},{b_t:.9e},0,-32767,32767,1,1,P",
        f"2,vibration,,,g,{a_v:.9e},{b_v:.9e},0,-32767,32767,1,1,P",
        "50", "1", f"{int(m.FS)},{n}",
        "01/01/2026,00:00:00.000000", "01/01/2026,00:00:00.020000",
        "BINARY", "1", "0,0", "0,0", ""])
    rec = np.zeros(n, dtype=[("n", "<u4"), ("t", "<u4"), ("tr", "<i2"), ("vi", "<i2")])
    rec["n"] = np.arange(1, n + 1)
    rec["t"] = np.round(np.arange(n) * 1e6 / m.FS).astype(np.uint32)
    rec["tr"], rec["vi"] = ct, cv
    (directory / f"{stem}.dat").write_bytes(rec.tobytes())
    (directory / f"{stem}.cfg").write_text(cfg, newline="")


def quantise_travel(x):
    a, b = math.pi / 65534.0, math.pi / 2.0
    return np.clip(np.round((x - b) / a), -32767, 32767) * a + b


def _plan(rng, per_effect, controls, two_effect, outside):
    plan = []
    for name in m.CATALOGUE:
        for _ in range(per_effect):
            plan.append(({name: round(float(rng.uniform(0.7, 1.2)), 3)}, False))
    for _ in range(controls):
        plan.append(({}, False))
    for _ in range(two_effect):
        a, b = rng.choice(len(m.CATALOGUE), 2, replace=False)
        plan.append(({m.CATALOGUE[a]: round(float(rng.uniform(0.7, 1.2)), 3),
                      m.CATALOGUE[b]: round(float(rng.uniform(0.7, 1.2)), 3)}, False))
    for _ in range(outside):
        plan.append(({m.OUTSIDE: round(float(rng.uniform(0.7, 1.2)), 3)}, True))
    order = rng.permutation(len(plan))           # blind group ids
    return [plan[i] for i in order]


def write_groups(out_dir, *, seed, per_effect=4, controls=6, two_effect=4, outside=2,
                 captures_per_group=5) -> dict:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    plan = _plan(rng, per_effect, controls, two_effect, outside)
    groups = []
    n_motion = N_TOTAL - N_PRE
    for gi, (effects, is_out) in enumerate(plan):
        gid = f"F{seed}-g{gi:03d}"
        grng = np.random.default_rng([seed, gi])
        unit = _unit(grng)
        stems = []
        for ci in range(captures_per_group):
            p, _cond = _conditions(unit, grng)
            th_h = m.simulate(p, {}, n_motion)
            th_e = th_h if not effects else m.simulate(p, effects, n_motion)
            healthy = _place(th_h)
            clean = _place(m.sensor(th_e, effects))
            noisy = quantise_travel(clean + grng.normal(0.0, NOISE_RAD, N_TOTAL))
            vib = _vibration(_place(th_e), p["alpha0"], grng)
            stem = f"{gid}-c{ci}"
            write_comtrade(out, stem, noisy, vib)
            np.save(out / f"{stem}.clean.npy", clean.astype(np.float64))
            np.save(out / f"{stem}.healthy.npy", healthy.astype(np.float64))
            stems.append(stem)
        groups.append({"group": gid, "operation": "open", "effects": dict(effects),
                       "outside_catalogue": bool(is_out), "stems": stems})
    manifest = {"prototype": "f", "seed": seed, "groups": groups}
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return manifest
