"""Validation of the diagnosis's nuisance state (issue 29, P2): healthy groups of prototypes A, B
and C, their tolerances and per-operation conditions ON, must leave a joint gap at the noise floor
once each capture's reduced state (plus CO, α0 and τ for an opening) is profiled out.

Per prototype and operation: ``GROUPS`` units (±3 % tolerance), ``CAPTURES`` captures each under
the prototype's own drawn conditions. Prints χ²/n of the reduced fit (block means, whitened by the
noise model) and the gap per sample in noise units, gap/σ = √(max(χ²/n − 1, 0)/samples per block).
Writes bench/results/healthy_floor.json.
Run: PYTHONPATH=. .venv/bin/python bench/healthy_floor.py [--groups 3] [--captures 4]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from service.breaker_file import load_breaker  # noqa: E402
from service.diagnosis.windows import prepare  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def healthy_group(proto: str, operation: str, rng, captures: int):
    mod = importlib.import_module(f"service.prototypes.{proto}.groups" if proto in ("a", "b")
                                  else f"service.prototypes.{proto}")
    unit = mod.make_unit(rng, effects={}, tolerance=0.03)
    return [mod.simulate_capture(unit, operation, conditions=mod.draw_conditions(rng), rng=rng)[0]
            for _ in range(captures)]


def run(groups: int, captures: int, seed: int = 29):
    breaker = load_breaker(ROOT / "config/breakers/reference-252kV.toml")
    rows = []
    for proto in ("a", "b", "c"):
        for op in ("open", "close"):
            for g in range(groups):
                rng = np.random.default_rng([seed, ord(proto), op == "open", g])
                caps = healthy_group(proto, op, rng, captures)
                t0 = time.perf_counter()
                w = prepare(caps, breaker, op)
                chi = float(sum(np.sum(c.project_out(c.r) ** 2) for c in w.captures))
                n = w.n
                per = chi / n
                gap = float(np.sqrt(max(per - 1.0, 0.0) / w.block))
                rows.append({"prototype": proto, "operation": op, "group": g, "captures": captures,
                             "chi2_per_block": per, "gap_sigma": gap, "blocks": n,
                             "wall_s": time.perf_counter() - t0})
                print(f"{proto} {op:5} group {g}: χ²/n {per:6.3f}  gap/σ {gap:5.3f}  ({n} blocks, "
                      f"{rows[-1]['wall_s']:.1f} s)", flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--groups", type=int, default=3)
    ap.add_argument("--captures", type=int, default=4)
    ap.add_argument("--out", default=str(ROOT / "bench/results/healthy_floor.json"))
    a = ap.parse_args()
    rows = run(a.groups, a.captures)
    Path(a.out).write_text(json.dumps({"groups": a.groups, "captures": a.captures, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
