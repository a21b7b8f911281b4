"""Train, calibrate and measure the diagnosis's scorer on the gap corpus (issue 48 items 2, 3, 7).

Reads var/gap48/rows_{clean,realistic,crank}.jsonl with their oracle labels (``corpus.rows``),
simulates nothing, and reports:

* the method's own answers before the scorer (the softmax of the evidence and its 0.9 threshold),
  on the same rows;
* **leave one prototype out** and **leave one sensor kind out**, nested: for each held-out group
  the scorer is fitted on the others, and the set's q̂ (APS, 90 %) and the naming threshold
  (Learn then Test, wrong names ≤ 5 % at 90 % confidence) are calibrated on the others' own
  held-out probabilities (an inner leave-one-out over the other groups): nothing of the held-out
  group enters its scorer or its thresholds;
* every fraction with its Wilson 95 % interval.

With ``--ship`` it writes service/diagnosis/scorer.json: the scorer fitted on every labelled row,
q̂ and λ calibrated on the leave-one-prototype-out probabilities of all of them, and the
provenance. Prints a Markdown summary and writes bench/results/gap_scorer.json (with ``uptime``).
Run: HVCB_SHARED_DIR=/work/shared .venv/bin/python bench/gap_scorer.py [--ship]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import subprocess
from collections import Counter
from pathlib import Path

import numpy as np

from service.studies.gap import corpus, train
from service.studies.gap.scoring import wilson

ROOT = Path(__file__).resolve().parents[1]


def _frac(k, n):
    return {"k": int(k), "n": int(n), "fraction": (k / n) if n else None, "wilson95": wilson(int(k), int(n))}


def answers(items, probs, qhat, lam):
    out = []
    for it, p in zip(items, probs):
        names = it["names"]
        top = int(np.argmax(p))
        s = train.aps_set(names, p, qhat)
        named = lam is not None and float(p[top]) >= lam
        out.append({"label": names[it["y"]], "top": names[top], "p_top": float(p[top]), "set": s,
                    "named": names[top] if named else None, "prototype": it["row"]["prototype"],
                    "variant": it["row"]["variant"], "n": it["row"]["n"]})
    return out


def figures(ans) -> dict:
    det = [a for a in ans if a["label"] != "none"]
    healthy = [a for a in ans if a["label"] == "none"]
    pairs = [a for a in ans if "+" in a["label"]]
    hi = [a for a in ans if a["p_top"] >= 0.9]
    return {
        "rows": len(ans),
        "wrong_names": _frac(sum(a["named"] is not None and a["named"] != a["label"] for a in ans), len(ans)),
        "healthy_none": _frac(sum(a["named"] == "none" for a in healthy), len(healthy)),
        "healthy_set_none_only": _frac(sum(a["set"] == ["none"] for a in healthy), len(healthy)),
        "set_holds_truth_detectable": _frac(sum(a["label"] in a["set"] for a in det), len(det)),
        "set_holds_truth_all": _frac(sum(a["label"] in a["set"] for a in ans), len(ans)),
        "mean_set_size_detectable": float(np.mean([len(a["set"]) for a in det])) if det else None,
        "right_name_detectable": _frac(sum(a["named"] == a["label"] for a in det), len(det)),
        "top1_detectable": _frac(sum(a["top"] == a["label"] for a in det), len(det)),
        "stated_09_right": _frac(sum(a["top"] == a["label"] for a in hi), len(hi)),
        "pairs_in_set": _frac(sum(a["label"] in a["set"] for a in pairs), len(pairs)),
    }


def method_own(rows) -> dict:
    """The method's own answers before the scorer (its softmax and its threshold)."""
    ans = []
    for r in rows:
        if r.get("error") or r.get("failed") or r.get("label") is None or not r.get("status"):
            continue           # rows diagnosed to their features only carry no answer of the method's
        lab = train.hyp_label(r["label"])
        top = r.get("answer")
        named = None
        if r.get("status") in ("named", "none", "unexplained"):
            named = {"unexplained": train.OUTSIDE}.get(r["status"], top if r["status"] == "named" else "none")
            named = "+".join(r.get("effects") or []) if r["status"] == "named" else named
        ans.append({"label": lab, "top": top, "p_top": float(r.get("answer_probability") or 0.0),
                    "set": [top], "named": named, "prototype": r["prototype"], "variant": r["variant"],
                    "n": r.get("n")})
    f = figures(ans)
    for k in ("healthy_set_none_only", "set_holds_truth_detectable", "set_holds_truth_all",
              "mean_set_size_detectable", "pairs_in_set"):
        f.pop(k)
    return f


def nested(items, key):
    """Held-out answers per group of ``key`` (module docstring)."""
    groups = sorted({key(it["row"]) for it in items})
    ans, cal = [], {}
    for g in groups:
        test = [it for it in items if key(it["row"]) == g]
        rest = [it for it in items if key(it["row"]) != g]
        inner = train.crossval(rest, key)
        ok = [(it, p) for it, p in zip(rest, inner) if p is not None]
        q = train.aps_quantile([train.aps_score(p, it["y"]) for it, p in ok])
        lam, _ = train.name_threshold([p for _, p in ok], [it["y"] for it, _ in ok])
        sc = train.fit(rest)
        probs = [train.probabilities(sc, it) for it in test]
        ans += answers(test, probs, q, lam)
        cal[g] = {"qhat": q, "lambda": lam, "calibration_rows": len(ok), "test_rows": len(test)}
    return ans, cal


def by(ans, field):
    return {v: figures([a for a in ans if a[field] == v]) for v in sorted({a[field] for a in ans})}


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", type=Path, default=ROOT / "var/gap48")
    ap.add_argument("--ship", action="store_true")
    ap.add_argument("--l2", type=float, default=train.L2, help="the scorer's L2 (default: the one fixed beforehand)")
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/gap_scorer.json")
    args = ap.parse_args(argv)
    train.L2 = args.l2
    up0 = uptime()
    rows = [r for v in corpus.VARIANTS for r in corpus.rows(args.corpus, v)]
    items, left = train.dataset(rows)
    reasons = Counter(why.split(":")[0] for _, why in left)
    labels = Counter(train.hyp_label(it["row"]["label"]) for it in items)
    out = {"uptime_start": up0, "corpus": str(args.corpus), "rows": len(rows), "labelled_rows": len(items),
           "left_out": dict(reasons), "labels": dict(labels),
           "by_variant": dict(Counter(r["variant"] for r in rows)),
           "by_prototype": dict(Counter(r["prototype"] for r in rows)),
           "method_own": {"all": method_own(rows), "by_variant": {v: method_own([r for r in rows if r["variant"] == v])
                                                                  for v in corpus.VARIANTS}}}
    lopo, cal_p = nested(items, lambda r: r["prototype"])
    loso, cal_s = nested(items, lambda r: r["variant"])
    out["lopo"] = {"all": figures(lopo), "by_prototype": by(lopo, "prototype"), "by_variant": by(lopo, "variant"),
                   "by_n": by(lopo, "n"), "calibration": cal_p}
    out["loso"] = {"all": figures(loso), "by_variant": by(loso, "variant"), "calibration": cal_s}
    if args.ship:
        oof = train.crossval(items, lambda r: r["prototype"])
        ok = [(it, p) for it, p in zip(items, oof) if p is not None]
        q = train.aps_quantile([train.aps_score(p, it["y"]) for it, p in ok])
        lam, tested = train.name_threshold([p for _, p in ok], [it["y"] for it, _ in ok])
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, check=False).stdout.strip()
        meta = {"provenance": {"corpus": "var/gap48 (bench/gap_corpus.py, seed 4848)", "rows": len(items),
                               "prototypes": sorted({it["row"]["prototype"] for it in items}),
                               "sensor_kinds": sorted({it["row"]["variant"] for it in items}),
                               "captures_per_group": sorted({it["row"]["n"] for it in items}),
                               "labels": dict(labels), "date": dt.date.today().isoformat(), "commit": commit,
                               "method": "conditional logit (McFadden 1974), L2 %g on standardised features" % train.L2},
                "heldout": {k: out["lopo"]["all"][k] for k in ("set_holds_truth_detectable", "wrong_names",
                                                                 "mean_set_size_detectable")},
                "set": {"method": "APS (Romano, Sesia & Candes 2020), randomisation fixed at U = 0", "alpha": train.ALPHA_SET,
                        "qhat": q, "calibrated_on": "leave-one-prototype-out probabilities of every labelled row"},
                "name": {"method": "Learn then Test (Angelopoulos et al. 2021), Hoeffding-Bentkus, fixed sequence",
                         "alpha": train.ALPHA_NAME, "delta": train.DELTA, "lambda": lam, "tested": tested[:12]}}
        sc = train.fit(items, meta=meta)
        path = ROOT / "service/diagnosis/scorer.json"
        path.write_text(json.dumps(sc.to_dict(), indent=1) + "\n")
        out["shipped"] = {"path": str(path.relative_to(ROOT)), "qhat": q, "lambda": lam}
    out["uptime_end"] = uptime()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1, default=float) + "\n")
    print(summary(out))
    return out


def _fmt(f):
    if f is None:
        return "—"
    if isinstance(f, float):
        return f"{f:.2f}"
    if f["n"] == 0:
        return "—"
    lo, hi = f["wilson95"]
    return f"{f['k']}/{f['n']} ({lo:.2f}–{hi:.2f})"


def summary(out) -> str:
    keys = ("wrong_names", "healthy_none", "set_holds_truth_detectable", "mean_set_size_detectable",
            "right_name_detectable", "top1_detectable", "stated_09_right", "pairs_in_set")
    lines = [f"rows {out['rows']}, labelled {out['labelled_rows']}, left out {out['left_out']}",
             f"labels {out['labels']}", "", "| check | method's own | LOPO | LOSO |", "|---|---|---|---|"]
    for k in keys:
        lines.append(f"| {k} | {_fmt(out['method_own']['all'].get(k))} | {_fmt(out['lopo']['all'][k])} | "
                     f"{_fmt(out['loso']['all'][k])} |")
    lines += ["", "LOPO by prototype:", "| prototype | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for p, f in out["lopo"]["by_prototype"].items():
        lines.append(f"| {p} | " + " | ".join(_fmt(f[k]) for k in keys) + " |")
    lines += ["", "LOSO by sensor kind:", "| held-out kind | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for p, f in out["loso"]["by_variant"].items():
        lines.append(f"| {p} | " + " | ".join(_fmt(f[k]) for k in keys) + " |")
    lines.append(f"\ncalibration LOPO {out['lopo']['calibration']}\ncalibration LOSO {out['loso']['calibration']}")
    lines.append(f"uptime {out['uptime_start']} → {out['uptime_end']}")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
