"""Naming under risk control and the answer as a set, leave one prototype out, on stored rows.

Re-reads the gap study's stored group rows (every group's diagnosis probabilities, truth and
oracle Δχ²; nothing is simulated or diagnosed again) and, for each prototype held out in turn,
chooses the set's conformal quantile (α = 0.1) and the naming thresholds (Learn then Test: wrong
names ≤ 5 % with 90 % confidence) on the others, then scores the held-out prototype
(service/studies/gap/risk.py). Prints the figures with Wilson 95 % intervals and writes
bench/results/gap_study/risk_lopo.json.

Run: PYTHONPATH=$PWD .venv/bin/python bench/gap_risk.py [ROWS.json ...]
"""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path

from service.studies.gap import risk

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = [ROOT / "bench/results/gap_study/issue36_abcd_quick/gap_groups.json",
           ROOT / "bench/results/gap_study/e_first_run/gap_groups.json"]
TARGETS = {"wrong_names": ("<=", 0.05), "healthy_none": (">=", 0.90), "names_right": (">=", 0.95),
           "set_holds_truth_detectable": (">=", 0.90), "named_detectable": (">=", 0.40),
           "two_effects": (">=", 7 / 8)}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", nargs="*", type=Path, default=None)
    ap.add_argument("--corpus", type=Path, help="a corpus written by bench/gap_corpus.py (var/gap_corpus)")
    ap.add_argument("--variant", default="clean", choices=("clean", "realistic"))
    args = ap.parse_args(argv)
    rows, sources = [], []
    if args.corpus:
        from service.studies.gap import corpus

        got = [r for r in corpus.rows(args.corpus, args.variant) if r.get("probabilities")]
        rows += got
        sources.append({"corpus": str(args.corpus), "variant": args.variant, "rows": len(got),
                        "refused": sum(1 for r in corpus.rows(args.corpus, args.variant) if r.get("error"))})
    for p in (args.rows or ([] if args.corpus else DEFAULT)):
        d = json.loads(p.read_text())
        got = [r for r in d["rows"] if "probabilities" in r and r.get("probabilities")]
        rows += got
        sources.append({"file": str(p.relative_to(ROOT)) if p.is_relative_to(ROOT) else str(p), "rows": len(got)})
    res = risk.lopo(rows)
    out = {"sources": sources, "alpha_set": 0.1, "alpha_name": 0.05, "delta": 0.1,
           "uptime": subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip(), "held_out": {}}
    cal_all = risk.learn_then_test(rows)
    q_all = risk.conformal_quantile([1.0 - risk.label_probabilities(r).get(risk.true_label(r), 0.0) for r in rows], 0.1)
    out["chosen_on_all"] = {"rule": {k: cal_all[k] for k in ("margin", "share", "n")}, "qhat": q_all}
    print(f"{'held out':9s} {'rule (margin, share)':22s} {'q̂':>6s}  " + "  ".join(f"{k}" for k in TARGETS))
    for p, r in res.items():
        f = risk.figures(r["answers"])
        row = {"rule": {k: r["rule"][k] for k in ("margin", "share", "n")}, "qhat": r["qhat"],
               "n_calibration": r["n_calibration"], "groups": len(r["answers"]), "figures": {}}
        cells = []
        for k, (op, t) in TARGETS.items():
            kk, n = f[k]
            lo, hi = risk.wilson(kk, n)
            v = kk / n if n else float("nan")
            ok = n > 0 and (v <= t if op == "<=" else v >= t)
            row["figures"][k] = {"k": kk, "n": n, "value": v, "wilson95": [lo, hi], "target": f"{op} {t:.3f}",
                                 "meets": bool(ok)}
            cells.append(f"{kk}/{n} ({100 * lo:.0f}–{100 * hi:.0f}) {'✓' if ok else '✗'}")
        row["figures"]["mean_set_size_detectable"] = f["mean_set_size_detectable"]
        out["held_out"][p] = row
        rule = f"({r['rule']['margin']}, {r['rule']['share']})"
        print(f"{p.upper():9s} {rule:22s} {r['qhat']:6.3f}  " + "  ".join(cells)
              + f"  size {f['mean_set_size_detectable'] if f['mean_set_size_detectable'] is None else round(f['mean_set_size_detectable'], 2)}")
    dest = ROOT / ("bench/results/gap_study/risk_lopo.json" if not args.corpus
                   else f"bench/results/gap_study/risk_lopo_corpus_{args.variant}.json")
    dest.write_text(json.dumps(out, indent=1, default=float) + "\n")
    return out


if __name__ == "__main__":
    main()
