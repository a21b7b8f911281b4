"""Prototype D's study set: groups of simulated captures with the truth of each, on disk.

A group is one simulated unit and ``captures_per_group`` captures of one operation under
conditions drawn per capture. The groups are shuffled before they are numbered, so a stem
(``pd_g012_c3``) reveals nothing; ``manifest.json`` says what each group holds.
"""

from __future__ import annotations

import json
import operator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

from drivers.capture import Capture
from service.acquisition.comtrade_writer import write_comtrade
from service.durable import write_durably
from service.prototypes.d.effects import EFFECTS, OPERATIONS, OUTSIDE, check_effects
from service.prototypes.d.noise import draw_noise, vibration_noise
from service.prototypes.d.simulate import SAMPLE_RATE_HZ, sensor_reading, true_travel
from service.prototypes.d.unit import (
    draw_conditions,
    draw_unit,
    physical,
    reduced_truth,
)

SAMPLES = {"open": 20_480, "close": 32_000}  # 160 ms and 250 ms, as the shared samples
PRETRIGGER_S = 0.020
TRAVEL_FULL_SCALE_RAD = 3.14159   # 0–180° transducer (config/breakers/reference-252kV.toml)
VIBRATION_FULL_SCALE_G = 1000.0
STRENGTH_RANGE = (0.5, 1.5)       # each effect's s, in units of its scale
_EPOCH = datetime(2026, 1, 5, 8, 0, tzinfo=UTC)


def _count(name, value, minimum=0):
    try:
        value = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be a whole number, got {value!r}") from None
    if value < minimum:
        raise ValueError(f"{name} must be at least {minimum}, got {value}")
    return value


def plan_groups(seed: int, per_effect: int, controls: int, two_effect: int,
                outside: int) -> list[dict]:
    """The groups' specs ({operation, effects: tuple of names, outside_catalogue}), shuffled
    deterministically for ``seed``."""
    rng = np.random.default_rng([seed, 2_147_483_647])
    plan = []
    for name in EFFECTS:
        for op in OPERATIONS[name]:
            plan += [{"operation": op, "effects": (name,), "outside_catalogue": False}] * per_effect
    for op in ("open", "close"):
        plan += [{"operation": op, "effects": (), "outside_catalogue": False}] * controls
    for k in range(two_effect):
        op = ("open", "close")[k % 2]
        names = [n for n in EFFECTS if op in OPERATIONS[n]]
        pair = rng.choice(len(names), size=2, replace=False)
        plan.append({"operation": op, "effects": tuple(sorted(names[i] for i in pair)),
                     "outside_catalogue": False})
    for name in OUTSIDE:
        for k in range(outside):
            ops = OPERATIONS[name]
            plan.append({"operation": ops[k % len(ops)], "effects": (name,),
                         "outside_catalogue": True})
    return [plan[i] for i in rng.permutation(len(plan))]


def simulate_capture(rng: np.random.Generator, operation: str, unit: dict, noise: dict,
                     effects: dict) -> dict:
    """One capture of ``operation`` by ``unit`` with ``effects``: conditions drawn from rng.
    Returns ``reading`` (noisy travel [rad]), ``clean`` (noiseless reading [rad]),
    ``vibration`` [g] and ``truth`` (the manifest's per-capture entry)."""
    check_effects(effects, operation)
    cond = draw_conditions(rng, PRETRIGGER_S)
    constants = physical(unit, cond)
    n = SAMPLES[operation]
    motion = true_travel(operation, constants, effects, cond["trigger_delay_s"], n, SAMPLE_RATE_HZ)
    clean = sensor_reading(motion.travel, unit, effects, SAMPLE_RATE_HZ)
    coloured, vibration, description = vibration_noise(rng, noise, motion.rate, motion.events_s,
                                                       SAMPLE_RATE_HZ)
    reading = clean + coloured + noise["white_sd_rad"] * rng.standard_normal(n)
    vibration = np.clip(vibration, -VIBRATION_FULL_SCALE_G, VIBRATION_FULL_SCALE_G)
    lo, hi = min(float(reading.min()), 0.0), max(float(reading.max()), TRAVEL_FULL_SCALE_RAD)
    truth = {"temperature_C": cond["temperature_C"], "trigger_delay_s": cond["trigger_delay_s"],
             **reduced_truth(operation, constants), "alpha0_rad": constants["alpha0"],
             "sensor_gain": unit["sensor_gain"], "sensor_offset_rad": unit["sensor_offset"],
             "noise": {"white_sd_rad": noise["white_sd_rad"],
                       "quantisation_lsb_rad": (hi - lo) / 65534, "coloured": description}}
    return {"reading": reading, "clean": clean, "vibration": vibration, "truth": truth}


def write_groups(out_dir, *, seed: int, per_effect: int = 4, controls: int = 6,
                 two_effect: int = 8, outside: int = 2, captures_per_group: int = 5) -> list[dict]:
    """Write prototype D's groups into out_dir (see the module docstring) and return the
    manifest: per group ``group``, ``operation``, ``effects`` {name: strength},
    ``outside_catalogue``, ``stems`` and ``truths`` (one per capture).

    Each capture is ``<stem>.cfg/.dat`` (16-bit BINARY COMTRADE, travel and vibration) and
    ``<stem>.clean.npy``: the noiseless reading of the same capture [rad], float64."""
    seed = _count("seed", seed)
    counts = {"per_effect": _count("per_effect", per_effect),
              "controls": _count("controls", controls),
              "two_effect": _count("two_effect", two_effect), "outside": _count("outside", outside)}
    captures_per_group = _count("captures_per_group", captures_per_group, 1)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out_dir {str(out)!r} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    manifest = []
    for gi, spec in enumerate(plan_groups(seed, **counts)):
        rng = np.random.default_rng([seed, gi])
        unit = draw_unit(rng)
        noise = draw_noise(rng)
        effects = {name: float(rng.uniform(*STRENGTH_RANGE)) for name in spec["effects"]}
        group = f"g{gi:03d}"
        stems, truths = [], []
        for ci in range(captures_per_group):
            cap = simulate_capture(rng, spec["operation"], unit, noise, effects)
            stem = f"pd_{group}_c{ci}"
            capture = Capture(travel=cap["reading"], sample_rate=SAMPLE_RATE_HZ,
                              vibration=cap["vibration"],
                              start_time=_EPOCH + timedelta(hours=gi, minutes=ci),
                              travel_limits=(0.0, TRAVEL_FULL_SCALE_RAD),
                              vibration_limits=(-VIBRATION_FULL_SCALE_G, VIBRATION_FULL_SCALE_G))
            write_comtrade(capture, out, stem, format="BINARY")
            np.save(out / f"{stem}.clean.npy", cap["clean"].astype(np.float64))
            stems.append(stem)
            truths.append(cap["truth"])
        manifest.append({"group": group, "operation": spec["operation"], "effects": effects,
                         "outside_catalogue": spec["outside_catalogue"], "stems": stems,
                         "truths": truths})
    write_durably(out / "manifest.json", json.dumps(manifest, indent=1) + "\n")
    return manifest
