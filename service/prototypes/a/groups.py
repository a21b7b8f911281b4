"""Groups of captures of one prototype-A breaker (unit) under varying conditions (issue 20).

Interface shared with prototypes B and C:

    make_unit(rng, *, effects=None, tolerance=0.03) -> unit
    draw_conditions(rng) -> {friction, buffer_damping, puffer, spring_charge, temperature_c}
    simulate_capture(unit, operation, *, conditions=None, rng, noise_rad=1.5e-3,
                     sample_rate_hz=128000) -> (Capture, truth)
    write_groups(out_dir, *, seed, per_effect=4, controls=6, two_effect=4, outside=2,
                 captures_per_group=5) -> manifest

A unit is one breaker: its reduced state drawn within ±tolerance of the reference breaker's
design values and its defects (``effects`` {name: strength in prototype A's units}). Conditions
change per capture: friction ±15 % (the resistance torque in BO and CC, and the strengths of
viscous, Stribeck and cam friction), buffer-oil damping −15…+20 % (DO, and through it the orifice force γ·DO·…;
from the temperature, −20…+40 °C, thicker when cold), puffer ±10 % (the puffer gas), spring
charge ±1 % (the springs' preload). Half of the resistance torques TOf/TCf is taken as
friction (the rest is contact load and gravity); at +15 % friction on the whole torque the
reference breaker's closing stalls with a realistic viscous or cam friction. Outside the catalogue: ``sensor_lag`` (a first-order travel
transducer lag of 100–250 µs at strength 1); a latch ramp is not modelled in A.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

from .effects import EFFECT_NAMES, OPERATIONS, REALISTIC, Effects

OUTSIDE = ("sensor_lag",)
OUTSIDE_OPERATIONS = {"sensor_lag": ("open", "close")}
FRICTION_EFFECTS = ("viscous_friction", "stribeck_friction", "cam_friction")
REFERENCE_BREAKER = Path(__file__).resolve().parents[3] / "config" / "breakers" / "reference-252kV.toml"
FRICTION_SHARE = 0.5   # share of the resistance torques TOf/TCf that is friction (the rest: contact load, gravity)


@lru_cache(maxsize=1)
def _breaker():
    """The reference 252 kV breaker, read once per process."""
    from service.breaker_file import load_breaker

    return load_breaker(REFERENCE_BREAKER)


def make_unit(rng, *, effects=None, tolerance=0.03) -> dict:
    b = _breaker()
    design = b.design_parameters()
    state = {k: float(design[k] * rng.uniform(1 - tolerance, 1 + tolerance))
             for k in ("AO", "BO", "DO", "EO", "AC", "BC", "CC")}
    state["DC"] = float(design["DC"])
    return {"prototype": "a", "state": state, "effects": dict(effects or {}),
            "lag_s": float(rng.uniform(100e-6, 250e-6))}


def draw_conditions(rng) -> dict:
    temp = float(rng.uniform(-20.0, 40.0))
    return {"friction": float(rng.uniform(0.85, 1.15)),
            "buffer_damping": float(1.20 - 0.35 * (temp + 20.0) / 60.0),
            "puffer": float(rng.uniform(0.90, 1.10)),
            "spring_charge": float(rng.uniform(0.99, 1.01)), "temperature_c": temp}


def _params(unit, operation, c):
    b = _breaker()
    s = unit["state"]
    if operation == "open":
        spring = b.kO * b.xO1 * b.rO / b.J2
        friction = FRICTION_SHARE * b.TOf / b.J2
        bo = s["BO"] + spring * (c["spring_charge"] - 1) - friction * (c["friction"] - 1)
        return {"AO": s["AO"], "BO": bo, "DO": s["DO"] * c["buffer_damping"], "EO": s["EO"]}
    cc = s["CC"] + FRICTION_SHARE * b.TCf / b.J2 * (c["friction"] - 1)
    return {"AC": s["AC"] * c["spring_charge"], "BC": s["BC"], "CC": cc, "DC": s["DC"]}


def simulate_capture(unit, operation, *, conditions=None, rng, noise_rad=1.5e-3, sample_rate_hz=128000):
    from service.acquisition.synthetic import synthesize_capture

    from .factory import make_prototype_simulator

    b = _breaker()
    c = conditions or {"friction": 1.0, "buffer_damping": 1.0, "puffer": 1.0, "spring_charge": 1.0,
                       "temperature_c": 20.0}
    strengths = {}
    for name, s in unit["effects"].items():
        if name in OUTSIDE or operation not in OPERATIONS[name]:
            continue
        # the orifice force is γ·DO·…: it follows the oil through DO already
        f = c["friction"] if name in FRICTION_EFFECTS else c["puffer"] if name == "puffer_gas" else 1.0
        strengths[name] = float(s) * f
    sim = make_prototype_simulator(b, Effects(**strengths), operation, method="fast")
    params = _params(unit, operation, c)
    lag = unit["lag_s"] * unit["effects"].get("sensor_lag", 0.0)
    cap, tr = synthesize_capture(b, operation, params, rng=rng, simulate=sim, fs=float(sample_rate_hz),
                                 noise_rad=0.0 if lag else noise_rad, bits=None if lag else 16)
    if lag:
        a = np.exp(-1.0 / (sample_rate_hz * lag))
        y, _ = lfilter([1.0 - a], [1.0, -a], cap.travel, zi=[a * cap.travel[0]])
        y = y + rng.normal(0.0, noise_rad, size=y.size)
        lsb = np.pi / (2**16 - 1)
        from dataclasses import replace
        cap = replace(cap, travel=np.round(y / lsb) * lsb)
    truth = {"operation": operation, "effects": {k: float(v) for k, v in unit["effects"].items()},
             "applied": strengths, "conditions": c, "params": params,
             "outside_catalogue": any(k in OUTSIDE for k in unit["effects"]),
             "t_motion_s": float(tr.t_motion), "noise_rad": float(noise_rad)}
    return cap, truth


def plan(rng, *, per_effect, controls, two_effect, outside):
    """[(operation, {effect: strength factor})] per group (factor × REALISTIC, 0.7–1.2)."""
    return group_plan(rng, EFFECT_NAMES, OPERATIONS, OUTSIDE, OUTSIDE_OPERATIONS, per_effect=per_effect,
                      controls=controls, two_effect=two_effect, outside=outside)


def group_plan(rng, names, operations, outside_names, outside_ops, *, per_effect, controls, two_effect, outside):
    out = []
    for name in names:
        ops = operations[name]
        out += [(ops[i % len(ops)], {name: float(rng.uniform(0.7, 1.2))}) for i in range(per_effect)]
    out += [(("open", "close")[i % 2], {}) for i in range(controls)]
    pairs = [(a, b, op) for op in ("open", "close") for i, a in enumerate(names) for b in names[i + 1:]
             if op in operations[a] and op in operations[b]]
    for j in rng.permutation(len(pairs))[:two_effect]:
        a, b, op = pairs[int(j)]
        out.append((op, {a: float(rng.uniform(0.7, 1.2)), b: float(rng.uniform(0.7, 1.2))}))
    for i in range(outside):
        name = outside_names[i % len(outside_names)]
        ops = outside_ops[name]
        out.append((ops[(i // len(outside_names)) % len(ops)], {name: float(rng.uniform(0.7, 1.2))}))
    return out


def write_groups(out_dir, *, seed, per_effect=4, controls=6, two_effect=4, outside=2, captures_per_group=5):
    rng = np.random.default_rng([seed, 20])
    groups = plan(rng, per_effect=per_effect, controls=controls, two_effect=two_effect, outside=outside)
    units = []
    for op, factors in groups:
        eff = {k: (f * REALISTIC[k] if k in REALISTIC else f) for k, f in factors.items()}
        units.append((op, factors, make_unit(rng, effects=eff)))
    return write_group_files(out_dir, "a", units, seed=seed, captures_per_group=captures_per_group,
                             simulate=simulate_capture, draw=draw_conditions, outside=OUTSIDE)



def write_group_files(out_dir, prototype, units, *, seed, captures_per_group, simulate, draw, outside):
    """``units``: [(operation, {effect: strength factor}, unit)]. One group per unit, its captures
    under freshly drawn conditions; stems do not reveal the effect. Returns the manifest."""
    import copy
    import json
    import os
    from pathlib import Path

    from service.acquisition.comtrade_writer import write_comtrade

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    seqs = np.random.SeedSequence([seed, 21]).spawn(len(units))
    groups = []
    for gi, ((op, factors, unit), ss) in enumerate(zip(units, seqs)):
        rng = np.random.default_rng(ss)
        stems, truths = [], []
        for j in range(captures_per_group):
            for _attempt in range(10):
                # a breaker that does not complete its stroke under these conditions (a closing
                # that stalls) leaves no record: the recorder sees no operation
                cond = draw(rng)
                # the same draws without noise: the noiseless travel the oracle of the study compares
                # against (service.studies.gap.oracle); a copy, so the written captures do not change
                twin = copy.deepcopy(rng)
                try:
                    cap, truth = simulate(unit, op, conditions=cond, rng=rng)
                    break
                except (ValueError, RuntimeError):
                    continue
            else:
                raise RuntimeError(f"group {gi}: {op} with {factors} never completes its stroke")
            stem = f"{prototype}g{gi:03d}c{j}"
            write_comtrade(cap, out, stem, format="BINARY")
            write_clean(out, stem, simulate, unit, op, cond, twin)
            stems.append(stem)
            truths.append(truth)
        groups.append({"group": f"{prototype}g{gi:03d}", "operation": op,
                       "effects": {k: float(v) for k, v in unit["effects"].items()},
                       "strength_factors": {k: float(v) for k, v in factors.items()},
                       "outside_catalogue": any(k in outside for k in factors),
                       "stems": stems, "truths": truths})
    manifest = {"prototype": prototype, "seed": seed, "groups": groups}
    tmp = out / ".manifest.json.tmp"
    tmp.write_text(json.dumps(manifest, indent=1, default=float) + "\n")
    os.replace(tmp, out / "manifest.json")
    return manifest


def write_clean(out, stem, simulate, unit, operation, conditions, rng) -> None:
    """``<stem>.clean.npy``: the capture's travel without noise [rad] (same unit, conditions and
    draws); ``<stem>.healthy.npy``: the same without the unit's effects (the truth that an absorbed
    effect's parameter bias is checked against). ``rng`` is a copy taken before the noisy capture."""
    import copy
    import dataclasses

    healthy = (dataclasses.replace(unit, effects={}) if dataclasses.is_dataclass(unit)
               else {**unit, "effects": {}})
    for suffix, u in (("clean", unit), ("healthy", healthy)):
        cap, _ = simulate(u, operation, conditions=conditions, rng=copy.deepcopy(rng), noise_rad=0.0)
        np.save(Path(out) / f"{stem}.{suffix}.npy", np.asarray(cap.travel, dtype=float))
