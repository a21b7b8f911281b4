"""Prototype D: how big each effect is, and how long the full study set takes to write.

1. Effect sizes: the design unit at 20 °C, latch at 20 ms, each (effect, operation) at s = 1
   against the same unit with every effect off; the rms change of the transducer reading over
   the motion (latch release to 5 ms after the end of the stroke) and its maximum [mrad].
2. Full set: ``write_groups`` with the defaults (90 groups × 5 captures) into a temporary
   directory, timed in CPU and wall-clock seconds on one core, after a warm-up that compiles
   the numba kernels (their cache is kept next to the sources).

Writes bench/results/prototype_d_dataset.json.

    python bench/prototype_d_dataset.py [--seed 2026] [--skip-full]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("NUMBA_NUM_THREADS", "1")
sys.path.insert(0, str(REPO))

import numpy as np

from service.prototypes.d import EFFECTS, OPERATIONS, OUTSIDE, write_groups
from service.prototypes.d.groups import SAMPLES
from service.prototypes.d.simulate import SAMPLE_RATE_HZ, sensor_reading, true_travel
from service.prototypes.d.unit import design, physical

RELEASE_S = 0.02


def effect_sizes() -> list[dict]:
    unit = design() | {"spring_sign": 1.0, "sensor_sign": 1.0}
    c = physical(unit, {"temperature_C": 20.0, "damping_factor": 1.0})
    rows = []
    for op in ("open", "close"):
        base = true_travel(op, c, {}, RELEASE_S, SAMPLES[op])
        ref = sensor_reading(base.travel, unit, {})
        end = base.events_s["end" if op == "open" else "closed"]
        window = slice(int(RELEASE_S * SAMPLE_RATE_HZ), int((end + 0.005) * SAMPLE_RATE_HZ))
        for name in EFFECTS + OUTSIDE:
            if op not in OPERATIONS[name]:
                continue
            motion = true_travel(op, c, {name: 1.0}, RELEASE_S, SAMPLES[op])
            change = sensor_reading(motion.travel, unit, {name: 1.0}) - ref
            rows.append({"effect": name, "operation": op,
                         "rms_mrad": round(1e3 * float(np.sqrt(np.mean(change[window] ** 2))), 3),
                         "max_mrad": round(1e3 * float(np.abs(change).max()), 3)})
    return rows


def main() -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--skip-full", action="store_true")
    args = ap.parse_args()
    result = {"effect_sizes_s1": effect_sizes()}
    for row in result["effect_sizes_s1"]:
        print(f"{row['effect']:22s} {row['operation']:5s} rms {row['rms_mrad']:8.2f} mrad"
              f"  max {row['max_mrad']:8.2f} mrad")
    if not args.skip_full:
        with tempfile.TemporaryDirectory() as tmp:
            write_groups(Path(tmp) / "warm", seed=args.seed, per_effect=0, controls=1,
                         two_effect=0, outside=0, captures_per_group=1)
            cpu, wall = time.process_time(), time.perf_counter()
            manifest = write_groups(Path(tmp) / "full", seed=args.seed)
            cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        result["full_set"] = {"seed": args.seed, "groups": len(manifest),
                              "captures": sum(len(g["stems"]) for g in manifest),
                              "cpu_s": round(cpu, 1), "wall_s": round(wall, 1)}
        print(f"full set: {result['full_set']}")
    return result


if __name__ == "__main__":
    RESULT = REPO / "bench" / "results" / "prototype_d_dataset.json"
    RESULT.write_text(json.dumps(main(), indent=1) + "\n")
    print(f"wrote {RESULT.relative_to(REPO)}")
