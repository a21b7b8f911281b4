"""Estimator accuracy at analyser sample rates (issue 24, item 3).

Decimates the shared 128 kS/s captures (/work/shared/samples or ../shared/samples) to 40, 20,
10 and 5 kS/s with scipy.signal.resample_poly (a polyphase FIR anti-alias filter, Kaiser
window) on both channels, fits each with the product's estimator (cold search, seed 1), and
reports the mean relative error (MRE) per parameter against the simulator's truth. Each rate
is fitted at ``--phases`` decimation phases (the decimated grid shifted by a fraction of its
own period: different noise samples of the same curve) so its MRE is not one noise draw; 128
kS/s has one phase. Target: at 10 kS/s the MRE of every opening parameter stays within 2x of
the 128 kS/s MRE. Writes bench/results/rate_accuracy.json.

    nice python bench/rate_accuracy.py [--phases 4] [--rates 40000,20000,10000,5000]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
from scipy.signal import resample_poly

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from service.acquisition.capture_file import read_capture  # noqa: E402
from service.breaker_file import load_breaker  # noqa: E402
from service.estimation import fit_capture  # noqa: E402
from service.estimation.window import FitError  # noqa: E402

OPENINGS = ("open-nominal", "open-nominal-ascii", "open-buffer-leak")
CLOSINGS = ("close-nominal",)
BASE = 128_000


def samples_dir() -> Path:
    for p in (REPO.parent / "shared" / "samples", Path("/work/shared/samples"), REPO / "shared" / "samples"):
        if p.is_dir():
            return p
    raise SystemExit("shared samples not found")


def decimated(cap, rate: int, phase: float):
    """``cap`` at ``rate`` [Hz]: anti-alias filtered and resampled; the grid starts ``phase``
    of the new period later (whole 128 kHz samples)."""
    if rate == BASE:
        return cap
    ratio = Fraction(rate, BASE)
    skip = int(round(phase * BASE / rate))

    def rs(x):
        return resample_poly(np.asarray(x[skip:], float), ratio.numerator, ratio.denominator, padtype="line")

    vib = rs(cap.vibration) if cap.vibration is not None else None
    return dataclasses.replace(cap, travel=rs(cap.travel), vibration=vib, sample_rate=float(rate),
                               travel_limits=None, vibration_limits=None, source=f"{cap.source}@{rate}")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--phases", type=int, default=4)
    ap.add_argument("--rates", default="40000,20000,10000,5000")
    args = ap.parse_args()
    d = samples_dir()
    breaker = load_breaker(REPO / "config/breakers/reference-252kV.toml")
    rates = [BASE] + [int(r) for r in args.rates.split(",")]
    rows = []
    for name in OPENINGS + CLOSINGS:
        cap = read_capture(d / f"{name}.cfg")
        truth = json.loads((d / f"{name}.truth.json").read_text())
        for rate in rates:
            for k in range(1 if rate == BASE else args.phases):
                c = decimated(cap, rate, k / args.phases)
                t0 = time.process_time()
                try:
                    r = fit_capture(c, breaker, truth["kind"], seed=1)
                except FitError as exc:
                    rows.append({"file": name, "rate_hz": rate, "phase": k, "error": str(exc)})
                    print(f"{name:20} {rate:6} phase {k}: refused: {exc}")
                    continue
                rel = {p: abs(v - truth["params"][p]) / abs(truth["params"][p]) for p, v in r.parameters.items()}
                rows.append({"file": name, "rate_hz": rate, "phase": k, "operation": truth["kind"],
                             "relative_error": rel, "rmse_over_noise": r.rmse_rad / r.noise_rad,
                             "cpu_s": time.process_time() - t0, "warnings": r.warnings})
                print(f"{name:20} {rate:6} phase {k}: " + " ".join(f"{p} {100 * e:.3f}%" for p, e in rel.items()),
                      flush=True)
    summary = {}
    for op, names in (("open", OPENINGS), ("close", CLOSINGS)):
        for rate in rates:
            ok = [r for r in rows if r["file"] in names and r["rate_hz"] == rate and "relative_error" in r]
            failed = sum(1 for r in rows if r["file"] in names and r["rate_hz"] == rate and "error" in r)
            if not ok:
                summary.setdefault(op, {})[str(rate)] = {"fits": 0, "refused": failed}
                continue
            params = ok[0]["relative_error"].keys()
            summary.setdefault(op, {})[str(rate)] = {
                "fits": len(ok), "refused": failed,
                "mre": {p: float(np.mean([r["relative_error"][p] for r in ok])) for p in params},
                "cpu_s_median": float(np.median([r["cpu_s"] for r in ok]))}
    base = summary["open"][str(BASE)]["mre"]
    at10 = summary["open"].get("10000", {}).get("mre")
    verdict = None
    if at10:
        verdict = {p: {"mre_128k": base[p], "mre_10k": at10[p], "ratio": at10[p] / base[p] if base[p] else None,
                       "within_2x": at10[p] <= 2 * base[p]} for p in base}
    out = {"what": "MRE per parameter vs sample rate (shared 128 kS/s samples, resample_poly anti-alias)",
           "phases": args.phases, "summary": summary, "target_10k_within_2x_of_128k": verdict, "rows": rows}
    (REPO / "bench/results").mkdir(exist_ok=True)
    (REPO / "bench/results/rate_accuracy.json").write_text(json.dumps(out, indent=1))
    print("\nMRE [%] per parameter")
    for op in summary:
        for rate, s in summary[op].items():
            mre = s.get("mre", {})
            print(f"{op:5} {int(rate) / 1e3:6.0f} kS/s fits {s['fits']:2} refused {s['refused']}: "
                  + " ".join(f"{p} {100 * v:.3f}" for p, v in mre.items()))
    if verdict:
        print("10 kS/s vs 128 kS/s (opening): " + ", ".join(
            f"{p} x{v['ratio']:.2f} {'ok' if v['within_2x'] else 'MISSED'}" for p, v in verdict.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
