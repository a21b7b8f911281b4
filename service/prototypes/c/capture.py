"""Prototype C: one simulated operation of a unit -> (Capture, truth)."""

from __future__ import annotations

import math

import numpy as np

from drivers.capture import Capture

from . import closing, opening, sensor
from . import effects as fx
from .mechanism import Unit, applied, reduced_params

PRE_S = 0.020            # rest before the latch releases the drive [s]
SHOCK_LEAD_S = 0.0004    # the latch strike precedes motion by the latch's own travel time [s]
POST_S = 0.030           # record kept after the end of stroke [s]
T_REF_C = 13.8           # temperature at which buffer_damping's viscosity factor is 1 [°C]
VISCOSITY_PER_K = 0.00766   # d ln(buffer damping)/dT [1/K]: -10..35 °C maps to 1.20..0.85
NOMINAL_CONDITIONS = {"friction": 1.0, "buffer_damping": 1.0, "puffer": 1.0, "spring_charge": 1.0,
                      "temperature_c": T_REF_C}
RANGES = {"friction": (0.85, 1.15), "buffer_damping": (0.85, 1.20), "puffer": (0.90, 1.10),
          "spring_charge": (0.99, 1.01), "temperature_c": (-10.0, 35.0)}


def draw_conditions(rng: np.random.Generator) -> dict:
    """One capture's conditions: relative factors and the mechanism temperature [°C].

    buffer_damping follows the oil viscosity at temperature_c (exp(-0.00766 (T - 13.8)), within
    ±3 % scatter), clipped to its range; the others are uniform in their ranges.
    """
    temp = float(rng.uniform(*RANGES["temperature_c"]))
    visc = math.exp(-VISCOSITY_PER_K * (temp - T_REF_C)) * rng.uniform(0.97, 1.03)
    return {"friction": float(rng.uniform(*RANGES["friction"])),
            "buffer_damping": float(np.clip(visc, *RANGES["buffer_damping"])),
            "puffer": float(rng.uniform(*RANGES["puffer"])),
            "spring_charge": float(rng.uniform(*RANGES["spring_charge"])),
            "temperature_c": temp}


def check_conditions(conditions) -> dict:
    """Conditions completed with nominal values; unknown keys or non-positive factors raise."""
    out = dict(NOMINAL_CONDITIONS)
    if conditions is None:
        return out
    if not isinstance(conditions, dict):
        raise ValueError(f"conditions must be a dict, got {type(conditions).__name__}")
    for k, v in conditions.items():
        if k not in out:
            raise ValueError(f"unknown condition {k!r}; known: {', '.join(out)}")
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"condition {k!r} must be a number, got {v!r}") from None
        if not math.isfinite(x) or (k != "temperature_c" and not 0.5 <= x <= 2.0):
            raise ValueError(f"condition {k!r} = {v!r} is outside the physical range "
                             f"({'finite' if k == 'temperature_c' else '0.5..2.0 relative'})")
        out[k] = x
    return out


def simulate_capture(unit: Unit, operation: str, *, conditions=None, rng, noise_rad: float = 1.5e-3,
                     sample_rate_hz: float = 128000) -> tuple:
    """Simulate one ``operation`` ('open' or 'close') of ``unit``; returns (Capture, truth dict)."""
    fx.check_operation(unit.effects, operation)
    cond = check_conditions(conditions)
    if not (math.isfinite(noise_rad) and noise_rad >= 0):
        raise ValueError(f"noise_rad must be a non-negative number, got {noise_rad!r}")
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz >= 1000):
        raise ValueError(f"sample_rate_hz must be at least 1000 Hz, got {sample_rate_hz!r}")
    if not isinstance(rng, np.random.Generator):
        raise ValueError("rng must be a numpy Generator (np.random.default_rng(seed))")
    c = applied(unit.constants, cond)
    s = {k: v for k, v in unit.effects.items() if v > 0}
    fs = float(sample_rate_hz)
    extra = {}
    if operation == "open":
        model = opening.build(c, s, unit.shapes, puffer_scale=cond["puffer"])
        segs, ev = opening.integrate(model, POST_S + 2.0 / fs)
        t_end = ev["peak"]
        t = np.arange(int(math.ceil((PRE_S + t_end + POST_S) * fs))) / fs
        rel = t - PRE_S
        true = np.where(rel > 0, opening.sample(segs, rel, 0), 0.0)
        start = _first_motion(lambda x: opening.sample(segs, x, 0))
        w_eng = float(opening.sample(segs, np.array([ev["engage"]]), 1)[0])
        events = [(PRE_S - SHOCK_LEAD_S, rng.uniform(250.0, 450.0)),
                  (PRE_S + ev["engage"], 0.8 * w_eng), (PRE_S + t_end, rng.uniform(8.0, 15.0))]
        extra["t_buffer_engage_s"] = PRE_S + float(ev["engage"])
    else:
        model = closing.ClosingModel(c=c, s=s, sh=unit.shapes, friction=cond["friction"])
        sol, t_end = closing.integrate(model)
        t = np.arange(int(math.ceil((PRE_S + t_end + POST_S) * fs))) / fs
        rel = t - PRE_S
        true = closing.travel(model, sol, t_end, rel)
        start = _first_motion(lambda x: sol.sol(np.clip(x, 0, t_end))[0] - c["theta1_start"])
        lift = _first_motion(lambda x: 1.0 - closing.travel(model, sol, t_end, x), limit=t_end, tol=1e-6)
        events = [(PRE_S - SHOCK_LEAD_S, rng.uniform(150.0, 300.0)), (PRE_S + t_end, rng.uniform(350.0, 600.0))]
        if s.get("contact_wipe"):
            touch = _first_motion(lambda x: unit.shapes["contact_wipe"]["wipe_rad"] + 1e-9
                                  - closing.travel(model, sol, t_end, x), limit=t_end, tol=0.0)
            events.append((PRE_S + touch, rng.uniform(15.0, 30.0)))
        extra["t_travel_start_s"] = PRE_S + lift
    travel = sensor.record_travel(true, s, unit.shapes, fs, noise_rad, rng)
    vib = sensor.vibration(t, events, rng)
    capture = Capture(travel=travel, sample_rate=fs, vibration=vib, source="prototype-c",
                      travel_limits=sensor.TRAVEL_SPAN, vibration_limits=sensor.VIBRATION_SPAN)
    outside = any(k in fx.OUTSIDE for k in s)
    truth = {
        "operation": operation,
        "effects": {k: float(v) for k, v in s.items()},
        "outside_catalogue": bool(outside),
        "shapes": {k: dict(v) for k, v in unit.shapes.items() if k in s},
        "constants": {k: float(v) for k, v in unit.constants.items()},
        "applied_constants": {k: float(v) for k, v in c.items()},
        "conditions": dict(cond),
        "t_shock_s": PRE_S - SHOCK_LEAD_S,
        "t_release_s": PRE_S,
        "t_motion_s": PRE_S + start,
        "t_end_of_stroke_s": PRE_S + float(t_end),
        "params": reduced_params(c, operation),
        "noise_rad_sd": float(noise_rad),
        "sample_rate_hz": fs,
        **extra,
    }
    return capture, truth


def _first_motion(f, limit: float = 0.02, tol: float = 1e-12) -> float:
    """First time [s from release] where f(t) > tol, on a 1 µs grid (0 when it moves at once)."""
    grid = np.arange(0.0, limit, 1e-6)
    moved = np.nonzero(np.asarray(f(grid)) > tol)[0]
    if moved.size == 0:
        return float(limit)
    i = int(moved[0])
    return 0.0 if i <= 1 else float(grid[i - 1])
