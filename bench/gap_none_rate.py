"""Benchmark: the measured false rate of ``none_test`` (``none`` decided before any scorer) on
healthy groups, against its designed level.

Healthy units of prototypes A and B (``service/prototypes``), conditions drawn per opening, groups
of ``--captures`` openings read clean: the reduced model is their model, so every refusal of
``none`` is a false one. The rate with its Wilson 95 % interval is compared with
``none_test.LEVEL``. The same groups read through the realistic sensor chain are reported beside
it, not as a false rate: the transducer's bow is a sensor nonlinearity the catalogue holds, so a
refusal there may be right. Only the reduced fits and the test run (no evidence, no scorer).

Prints and writes bench/results/gap_none_rate.json with ``uptime``.
Run: PYTHONPATH=$PWD .venv/bin/python bench/gap_none_rate.py [--groups 150] [--captures 5]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from pathlib import Path

os.environ.setdefault("HVCB_DIAGNOSIS_THREADS", "2")

import numpy as np  # noqa: E402
from scipy.stats import binomtest  # noqa: E402

from service.diagnosis.none_test import LEVEL, none_test  # noqa: E402
from service.diagnosis.windows import prepare  # noqa: E402
from service.studies.common import load_reference  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def healthy_group(prototype: str, n: int, seed: int, sensor: str) -> list:
    from bench.diagnose_speed import group

    return group(prototype, {}, n, seed, sensor)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--groups", type=int, default=150, help="healthy groups per prototype")
    ap.add_argument("--captures", type=int, default=5)
    ap.add_argument("--sensors", default="clean,realistic")
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/gap_none_rate.json")
    args = ap.parse_args(argv)
    breaker = load_reference()
    up0 = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    t0 = time.perf_counter()
    rows = []
    for proto in ("a", "b"):
        for sensor in args.sensors.split(","):
            for g in range(args.groups):
                seed = 5400 + 1000 * (proto == "b") + g
                w = prepare(healthy_group(proto, args.captures, seed, sensor), breaker, "open")
                nt = none_test(w)
                rows.append({"prototype": proto, "sensor": sensor, "seed": seed, "p_value": nt.p_value,
                             "statistic": nt.statistic, "df_gap": nt.df_gap, "df_noise": nt.df_noise,
                             "none": nt.consistent})
    out = {"bench": "gap_none_rate", "level": LEVEL, "captures": args.captures, "groups_per_prototype": args.groups,
           "uptime_start": up0, "summary": {}}
    for sensor in args.sensors.split(","):
        for proto in ("a", "b", "a+b"):
            sel = [r for r in rows if r["sensor"] == sensor and (proto == "a+b" or r["prototype"] == proto)]
            k = sum(not r["none"] for r in sel)
            ci = binomtest(k, len(sel)).proportion_ci(confidence_level=0.95, method="wilson")
            lo, hi = ci.low, ci.high
            out["summary"][f"{proto} {sensor}"] = {"groups": len(sel), "refused": k, "rate": k / len(sel),
                                                   "wilson95": [float(lo), float(hi)],
                                                   "median_p": float(np.median([r["p_value"] for r in sel]))}
            print(f"{proto:3s} {sensor:9s}: none refused on {k:3d} of {len(sel)} healthy groups = {k / len(sel):.3f} "
                  f"(Wilson 95 % {lo:.3f}-{hi:.3f}; designed {LEVEL}{'' if sensor == 'clean' else ', not a false rate'})")
    out["seconds"] = time.perf_counter() - t0
    out["uptime_end"] = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    out["rows"] = rows
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(f"{out['seconds']:.0f} s; {out['uptime_end']}")
    return out


if __name__ == "__main__":
    main()
