"""Prototype E: study-set writer (groups of captures of simulated units)."""
from __future__ import annotations

import hashlib
import json
import math
import numbers
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

from . import model as M
from . import sensor as SN
from . import sim

EFFECTS = ("linkage_kinematics", "orifice_buffer", "puffer_gas", "rod_elasticity",
           "stribeck_friction", "viscous_friction", "spring_nonlinearity",
           "sensor_nonlinearity", "cam_friction", "contact_wipe")
OUTSIDE = ("spring_surge",)
OPERATIONS = {
    "linkage_kinematics": ("open", "close"),
    "orifice_buffer": ("open",),
    "puffer_gas": ("open",),
    "rod_elasticity": ("open", "close"),
    "stribeck_friction": ("open", "close"),
    "viscous_friction": ("open", "close"),
    "spring_nonlinearity": ("open", "close"),
    "sensor_nonlinearity": ("open", "close"),
    "cam_friction": ("close",),
    "contact_wipe": ("close",),
    "spring_surge": ("open", "close"),
}
STRENGTH_RANGE = (0.5, 1.5)
EPOCH = datetime(2026, 3, 2, 8, 0, 0, tzinfo=timezone.utc)


def _rng(seed: int, *keys) -> np.random.Generator:
    h = hashlib.sha256(repr((int(seed),) + tuple(keys)).encode()).digest()
    return np.random.default_rng(int.from_bytes(h[:8], "little"))


def capture(op: str, u: M.Unit, effects: dict, cond: M.Conditions, rng: np.random.Generator):
    """Simulate one capture.  Returns (travel, vibration, clean, healthy, info)."""
    fs = M.SAMPLE_RATE
    n = M.N_OPEN if op == "open" else M.N_CLOSE
    t0 = M.PRETRIGGER_S + cond.trigger_delay_s
    r = sim.simulate(op, u, cond.temperature_C, effects, t0, n)
    rh = sim.simulate(op, u, cond.temperature_C, {}, t0, n)
    s_nl = float(effects.get("sensor_nonlinearity", 0.0))
    clean = SN.reading(r["tau"], u, s_nl)
    healthy = SN.reading(rh["tau"], u, 0.0)
    vib_rad, vib_desc = SN.torsional_vibration(op, r["tau"], u, u.J2, fs, t0, rng, r["x_contact"])
    travel = SN.noisy_reading(r["tau"] + vib_rad, u, s_nl, rng)
    accel = SN.accelerometer(op, r["tau"], u, u.J2, fs, t0, rng, r["x_contact"])
    if op == "open":
        i_end = int(np.argmax(r["tau"]))
        completed = bool(r["tau"].max() > 0.8)
    else:
        i_end = int(np.nonzero(r["tau"] <= r["tau"].min() + 1e-9)[0][0])
        completed = bool(r["tau"].min() < 0.02)
    info = dict(t_motion_start=t0, t_max=i_end / fs, vibration=vib_desc, completed=completed)
    return travel, accel, clean, healthy, info


def _check_count(name, v, minimum):
    if isinstance(v, bool) or not isinstance(v, numbers.Integral):
        raise ValueError(f"{name} must be a whole number, not {v!r}")
    if v < minimum:
        raise ValueError(f"{name} must be at least {minimum}, not {v}")
    return int(v)


def plan_groups(seed: int, per_effect: int, controls: int, two_effect: int, outside: int):
    rng = _rng(seed, "plan")
    groups = []
    for e in EFFECTS:
        for op in OPERATIONS[e]:
            for _ in range(per_effect):
                groups.append(dict(operation=op, effects=[e], outside=False))
    for op in ("open", "close"):
        for _ in range(controls):
            groups.append(dict(operation=op, effects=[], outside=False))
    for k in range(two_effect):
        op = ("open", "close")[k % 2]
        valid = [e for e in EFFECTS if op in OPERATIONS[e]]
        pair = rng.choice(len(valid), size=2, replace=False)
        groups.append(dict(operation=op, effects=sorted(valid[i] for i in pair), outside=False))
    for e in OUTSIDE:
        ops = OPERATIONS[e]
        for k in range(outside):
            groups.append(dict(operation=ops[k % len(ops)], effects=[e], outside=True))
    order = rng.permutation(len(groups))
    return [groups[i] for i in order]


def write_groups(out_dir, *, seed: int, per_effect: int = 4, controls: int = 6,
                 two_effect: int = 8, outside: int = 2, captures_per_group: int = 5) -> list[dict]:
    """Write a study set of prototype E into out_dir; return (and write) the manifest."""
    from drivers.capture import Capture
    from service.acquisition.comtrade_writer import write_comtrade
    from service.durable import write_durably

    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise ValueError(f"seed must be an integer, not {seed!r}")
    per_effect = _check_count("per_effect", per_effect, 0)
    controls = _check_count("controls", controls, 0)
    two_effect = _check_count("two_effect", two_effect, 0)
    outside = _check_count("outside", outside, 0)
    captures_per_group = _check_count("captures_per_group", captures_per_group, 1)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out_dir {out} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    plan = plan_groups(seed, per_effect, controls, two_effect, outside)
    if not plan:
        raise ValueError("nothing to write: every group count is zero")

    manifest = []
    for gi, g in enumerate(plan):
        gname = f"g{gi:03d}"
        rng = _rng(seed, "group", gi)
        unit = M.draw_unit(rng)
        lo, hi = STRENGTH_RANGE
        effects = {e: float(round(rng.uniform(lo, hi), 4)) for e in g["effects"]}
        op = g["operation"]
        # The reference breaker closes with a thin energy margin (a closing stalls at
        # TCf +35 %): a weak unit with two strong resistive effects in the cold can fail to
        # close.  A failed operation is an alarm, not a routine capture: its conditions are
        # drawn again (`redraws` in the truth); if a capture never completes the whole
        # group is simulated again with its strengths lowered by 10 %.
        for _lowering in range(10):
            sims = []
            for ci in range(captures_per_group):
                for attempt in range(20):
                    crng = _rng(seed, "capture", gi, ci, attempt)
                    cond = M.draw_conditions(crng)
                    res = capture(op, unit, effects, cond, crng)
                    if res[4]["completed"]:
                        break
                else:
                    break
                sims.append((cond, attempt) + res)
            if len(sims) == captures_per_group:
                break
            effects = {e: round(0.9 * v, 4) for e, v in effects.items()}
        else:
            raise RuntimeError(f"group {gname}: the simulated {op} never completes")
        stems, truths = [], []
        for ci, (cond, attempt, travel, accel, clean, healthy, info) in enumerate(sims):
            stem = f"pe_{gname}_c{ci}"
            start = EPOCH + timedelta(days=gi, hours=ci)
            cap = Capture(travel=travel, sample_rate=M.SAMPLE_RATE, vibration=accel,
                          start_time=start, travel_limits=(0.0, 3.14159),
                          vibration_limits=(-1000.0, 1000.0))
            write_comtrade(cap, out, stem, format="BINARY")
            np.save(out / f"{stem}.clean.npy", clean.astype(np.float64))
            np.save(out / f"{stem}.healthy.npy", healthy.astype(np.float64))
            truth = dict(
                temperature_C=cond.temperature_C, trigger_delay_s=cond.trigger_delay_s,
                t_motion_start=info["t_motion_start"], t_max=info["t_max"], redraws=attempt,
                **M.reduced_parameters(unit, cond.temperature_C),
                alpha0_rad=unit.alpha0,
                sensor_gain=unit.gain, sensor_zero_rad=unit.zero_rad,
                sensor_zero_m=unit.zero_m, lever_radius_m=unit.lever_r,
                lever_angle_rad=unit.lever_beta,
                noise=dict(
                    white_sd_m=unit.noise_sd_m,
                    white_sd_rad=unit.noise_sd_m / (M.LEVER_R * math.cos(M.LEVER_BETA)),
                    quantisation_lsb_m=SN.LSB, adc_bits=M.ADC_BITS,
                    torsional_modes_hz=list(unit.modes_hz),
                    torsional_modes_zeta=list(unit.modes_zeta),
                    struck=info["vibration"]["struck"],
                    rattle_rms_rad_at_peak_speed=info["vibration"]["rattle_rms_rad_at_peak_speed"],
                    kind="white (transducer) + 16-bit ADC + coloured torsional (struck modes, rattle)",
                ),
            )
            stems.append(stem)
            truths.append(truth)
        manifest.append(dict(group=gname, operation=op, effects=effects,
                             outside_catalogue=bool(g["outside"]), stems=stems, truths=truths))
    write_durably(out / "manifest.json", json.dumps(manifest, indent=1))
    return manifest
