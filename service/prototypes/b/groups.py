"""Groups of captures of one prototype-B breaker (unit) under varying conditions (issue 20).

Same interface as ``service.prototypes.a.groups`` (and prototype C):
``make_unit``, ``draw_conditions``, ``simulate_capture``, ``write_groups``.

A unit is one mechanism: its spread constants (kO, kC, TOf, TCf, cb, kb) drawn within
±tolerance of nominal, its defects ``effects`` {name: strength, 1 = realistic} and each
defect's shape drawn once (one physical defect, the same in every capture). Conditions per
capture: friction ±15 % (TOf, TCf and the viscous / Coulomb–Stribeck / cam-loss strengths),
buffer-oil damping −15…+20 % (cb; from the temperature −20…+40 °C), puffer ±10 % (the arc
chamber damping caec and the puffer-gas area), spring charge ±1 % (kO, kC).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.signal import lfilter

from ..a.groups import draw_conditions, group_plan, write_group_files  # noqa: F401 (same conditions)
from .capture import POST_S, PRE_S, simulate_motion, vibration
from .effects import EFFECTS, OPERATIONS, OUTSIDE, apply_effect, draw_shape
from .laws import Laws
from .mechanism import Effects
from .reference import reference_mechanism

FRICTION_EFFECTS = ("viscous_friction", "stribeck_friction", "cam_friction")


def make_unit(rng, *, effects=None, tolerance=0.03) -> dict:
    mech = reference_mechanism().spread(rng, tolerance)
    effects = dict(effects or {})
    shapes = {}
    for name in effects:
        ops = OPERATIONS[name]
        shapes[name] = {op: draw_shape(name, op, rng) for op in ops}
    return {"prototype": "b", "mechanism": mech, "effects": effects, "shapes": shapes}


def simulate_capture(unit, operation, *, conditions=None, rng, noise_rad=1.5e-3, sample_rate_hz=128000):
    c = conditions or {"friction": 1.0, "buffer_damping": 1.0, "puffer": 1.0, "spring_charge": 1.0,
                       "temperature_c": 20.0}
    m = unit["mechanism"]
    mech = replace(m, TOf=m.TOf * c["friction"], TCf=m.TCf * c["friction"], cb=m.cb * c["buffer_damping"],
                   caec=m.caec * c["puffer"], kO=m.kO * c["spring_charge"], kC=m.kC * c["spring_charge"])
    eff = Effects()
    for name, s in unit["effects"].items():
        if operation not in OPERATIONS[name]:
            continue
        f = c["friction"] if name in FRICTION_EFFECTS else c["puffer"] if name == "puffer_gas" else 1.0
        eff = apply_effect(eff, name, float(s) * f, unit["shapes"][name][operation])
    motion, t_stroke = simulate_motion(mech, eff, operation)
    fs = float(sample_rate_hz)
    n = int(round((PRE_S + t_stroke + POST_S) * fs))
    t_abs = np.arange(n) / fs
    true_travel = motion.sample(t_abs - PRE_S)["travel"]
    travel = true_travel + Laws(mech, eff).sensor_error(true_travel)
    if eff.sensor_lag > 0:
        a = math.exp(-1.0 / (fs * eff.sensor_lag))
        travel, _ = lfilter([1.0 - a], [1.0, -a], travel, zi=[a * travel[0]])
    travel = travel + rng.normal(0.0, noise_rad, size=n)
    lsb = np.pi / (2**16 - 1)
    travel = np.round(travel / lsb) * lsb
    shock = rng.uniform(350.0, 500.0)
    lead = rng.uniform(0.3e-3, 0.5e-3)
    vib = vibration(t_abs, [(PRE_S - lead, shock, rng.uniform(2200.0, 2800.0), 0.6e-3),
                            (PRE_S + t_stroke, 0.4 * shock, 1800.0, 0.7e-3)], rng)
    from drivers.capture import Capture
    cap = Capture(travel=travel, sample_rate=fs, vibration=vib, source=f"prototype-b-{operation}",
                  travel_limits=(0.0, math.pi), vibration_limits=(-1000.0, 1000.0))
    truth = {"operation": operation, "effects": {k: float(v) for k, v in unit["effects"].items()},
             "conditions": c, "outside_catalogue": any(k in OUTSIDE for k in unit["effects"]),
             "t_motion_s": PRE_S, "t_end_of_stroke_s": PRE_S + t_stroke, "noise_rad": float(noise_rad)}
    return cap, truth


def write_groups(out_dir, *, seed, per_effect=4, controls=6, two_effect=4, outside=2, captures_per_group=5):
    rng = np.random.default_rng([seed, 30])
    groups = group_plan(rng, EFFECTS, OPERATIONS, OUTSIDE, {k: OPERATIONS[k] for k in OUTSIDE},
                        per_effect=per_effect, controls=controls, two_effect=two_effect, outside=outside)
    units = [(op, factors, make_unit(rng, effects=factors)) for op, factors in groups]
    return write_group_files(out_dir, "b", units, seed=seed, captures_per_group=captures_per_group,
                             simulate=simulate_capture, draw=draw_conditions, outside=OUTSIDE)
