"""The cross-prototype blind study: ``hvcb diagnose`` against prototype B's captures (issue 11).

Prototype B (service/prototypes/b, docs/prototype-b.md) is an independently written
virtual prototype: the same ten effect names in its own equations, its constants spread ±6 %,
128 kHz 16-bit COMTRADE with 1.5 mrad noise. Its dataset is written to ``DIR/prototype_b/``
and the diagnoser reads only the files and the breaker; the manifest's truth labels are
compared afterwards.

Classes of a (true effect, operation) group, judged by the diagnoser's own evidence:

- ``detectable``: the gap is significant (omnibus χ² or a targeted likelihood-ratio test) on
  most of the group's captures: top-1 counts here;
- ``absorbed``: the gap stays at the noise floor on most captures and the a-priori
  identifiability check calls the effect absorbed: it must be listed in ``absorbed`` with its
  bias, and not named wrongly;
- ``undetectable``: the gap stays at the noise floor though the check expected it visible;
- ``outside``: effects outside the catalogue (sensor lag, latch ramp): never named.

The own-prototype study (``study.py``) classes by the a-priori check alone; the same figure is
given here as ``top1_distinguishable_a_priori`` for comparison.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

DEFAULT_SEED = 2026


def _diagnose_file(job: dict) -> dict:
    from ..acquisition.capture_file import read_capture
    from ..studies.common import load_reference
    from .diagnose import DiagnosisError, decide, diagnose

    breaker = load_reference()
    cfg = Path(job["cfg"])
    cap = read_capture(cfg, travel_channel=breaker.channels["travel"],
                       vibration_channel=breaker.channels["vibration"])
    t0 = time.perf_counter()
    try:
        res = diagnose([cap], breaker, job["operation"])
    except DiagnosisError as exc:
        return {**job, "verdict": "error", "error": str(exc)}
    runtime = time.perf_counter() - t0
    truth = job["truth"]
    ident = {v["effect"]: bool(v["distinguishable"]) for v in res["identifiability"]}
    cands = [{k: c.get(k) for k in ("effect", "delta_bic", "shrink", "holdout_shrink", "distinguishable",
                                    "strength", "shape", "after_p", "worst_phase_shrink", "in_region",
                                    "region_gap_share")} for c in res["candidates"]]
    ranked = [c["effect"] for c in res["candidates"]]
    in_cat = truth in ident
    loo = decide(res["candidates"], res["significant_chi2"], exclude=(truth,))[0] if in_cat else None
    return {**job, "verdict": res["verdict"], "status": res["status"],
            "explained_fraction": res["explained_fraction"], "ambiguous": res["ambiguous"],
            "ambiguous_family": res.get("ambiguous_family"),
            "significant_gap": res["significant_gap"], "gap_ratio": res["gap"]["ratio_to_noise"],
            "worst_phase": res["worst_phase"],
            "true_distinguishable": ident.get(truth) if in_cat else None,
            "true_absorbed_reported": (truth in {a["effect"] for a in res["absorbed"]}) if in_cat else None,
            "true_rank": (ranked.index(truth) + 1) if truth in ranked else None,
            "loo_verdict": loo, "candidates": cands, "runtime_s": runtime}


def _frac(xs):
    xs = list(xs)
    return float(np.mean(xs)) if xs else None


def classify_groups(rows) -> dict:
    """{(effect, operation): class} for the catalogued effects (see the module docstring)."""
    groups = {}
    for r in rows:
        if r["truth"] in ("none", "outside") or r["verdict"] == "error" or r["outside"]:
            continue
        groups.setdefault((r["truth"], r["operation"]), []).append(r)
    out = {}
    for key, rs in groups.items():
        sig = _frac(r["significant_gap"] for r in rs) >= 0.5
        dist = _frac(bool(r["true_distinguishable"]) for r in rs) >= 0.5
        out[key] = "detectable" if sig else ("undetectable" if dist else "absorbed")
    return out


def summarise(rows) -> dict:
    """The study's figures from the per-capture rows."""
    from ..prototypes.a import EFFECT_NAMES

    ok = [r for r in rows if r["verdict"] != "error"]
    cls = classify_groups(ok)
    det = [r for r in ok if cls.get((r["truth"], r["operation"])) == "detectable"]
    absd = [r for r in ok if cls.get((r["truth"], r["operation"])) == "absorbed"]
    und = [r for r in ok if cls.get((r["truth"], r["operation"])) == "undetectable"]
    controls = [r for r in ok if r["truth"] == "none"]
    outside = [r for r in ok if r["outside"]]
    named = set(EFFECT_NAMES)

    def wrong(r):
        return r["verdict"] in named and r["verdict"] != r["truth"]

    per_group = {}
    for (e, op), c in sorted(cls.items()):
        rs = [r for r in ok if r["truth"] == e and r["operation"] == op]
        per_group[f"{e}/{op}"] = {
            "class": c, "captures": len(rs), "top1": _frac(r["verdict"] == e for r in rs),
            "wrong_name": _frac(wrong(r) for r in rs), "none": _frac(r["verdict"] == "none" for r in rs),
            "unexplained": _frac(r["verdict"] == "unexplained" for r in rs),
            "ranked_first": _frac(r["true_rank"] == 1 for r in rs),
            "listed_absorbed": _frac(bool(r["true_absorbed_reported"]) for r in rs),
            "median_shrink": float(np.median([next((c["shrink"] for c in r["candidates"] if c["effect"] == e), 0.0)
                                              for r in rs])),
            "verdicts": {v: sum(r["verdict"] == v for r in rs) for v in sorted({r["verdict"] for r in rs})},
        }
    labels = sorted({r["verdict"] for r in rows})
    truths = sorted({r["truth"] for r in rows})
    conf = {t: {v: sum(r["truth"] == t and r["verdict"] == v for r in rows) for v in labels} for t in truths}
    return {
        "groups": per_group, "confusion": conf,
        "detectable_groups": sorted(k for k, v in per_group.items() if v["class"] == "detectable"),
        "absorbed_groups": sorted(k for k, v in per_group.items() if v["class"] == "absorbed"),
        "undetectable_groups": sorted(k for k, v in per_group.items() if v["class"] == "undetectable"),
        "top1_detectable": _frac(r["verdict"] == r["truth"] for r in det),
        "ranked_first_detectable": _frac(r["true_rank"] == 1 for r in det),
        "top1_distinguishable_a_priori": _frac(
            r["verdict"] == r["truth"] for r in ok if r["truth"] in named
            and _frac(bool(q["true_distinguishable"]) for q in ok
                      if q["truth"] == r["truth"] and q["operation"] == r["operation"]) >= 0.5),
        "top1_all_effects": _frac(r["verdict"] == r["truth"] for r in ok if r["truth"] in named),
        "control_none_rate": _frac(r["verdict"] == "none" for r in controls),
        "wrong_name_rate_all": _frac(wrong(r) or (r["outside"] and r["verdict"] in named)
                                     or (r["truth"] == "none" and r["verdict"] in named) for r in ok),
        "absorbed_listed_absorbed": _frac(bool(r["true_absorbed_reported"]) for r in absd),
        "absorbed_wrong_name": _frac(wrong(r) for r in absd),
        "undetectable_none_or_right": _frac(r["verdict"] in ("none", r["truth"]) for r in und),
        "outside_named": sum(r["verdict"] in named for r in outside), "outside_captures": len(outside),
        "status_counts": {s: sum(r.get("status") == s for r in ok)
                          for s in ("explained", "partly_explained", "ambiguous", "unexplained", "none")},
        "errors": len(rows) - len(ok),
        "runtime_s_median": float(np.median([r["runtime_s"] for r in ok])) if ok else None,
        "runtime_s_max": float(np.max([r["runtime_s"] for r in ok])) if ok else None,
    }


TARGETS = {"top1_detectable": 0.90, "control_none_rate": 0.90, "wrong_name_rate_all": 0.05,
           "absorbed_listed_absorbed": 1.0}


def run_cross_study(out_dir: Path, *, seed: int = DEFAULT_SEED, workers: int = 2, per_effect: int = 10,
                    controls: int = 40, outside: int = 3, limit: int | None = None) -> dict:
    """Write prototype B's dataset into ``out_dir/prototype_b`` (reused when its manifest is
    there for the same seed and sizes) and diagnose every capture blind. Returns the summary
    (also ``gap_cross.json`` and ``gap_cross.md``). ``limit`` diagnoses only the first captures
    (quick checks)."""
    from ..prototypes.b import write_dataset
    from ..studies.common import pool_map
    from ..studies.report import write_json

    out = Path(out_dir)
    ds = out / "prototype_b"
    stamp = {"seed": seed, "per_effect": per_effect, "controls": controls, "outside": outside}
    stamp_file = ds / "dataset.json"
    if (ds / "manifest.json").exists() and stamp_file.exists() and json.loads(stamp_file.read_text()) == stamp:
        manifest = json.loads((ds / "manifest.json").read_text())
    else:
        manifest = write_dataset(ds, seed=seed, per_effect=per_effect, controls=controls, outside=outside)
        stamp_file.write_text(json.dumps(stamp))
    jobs = [{"cfg": str(ds / f"{m['stem']}.cfg"), "stem": m["stem"], "operation": m["operation"],
             "truth": ("outside" if m["outside_catalogue"] else (m["effect"] or "none")),
             "outside": bool(m["outside_catalogue"]), "outside_effect": m["effect"] if m["outside_catalogue"] else None,
             "strength": m["strength"]} for m in manifest]
    if limit:
        jobs = jobs[:limit]
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    t0 = time.perf_counter()
    rows = pool_map(_diagnose_file, jobs, max(1, int(workers)))
    data = {"seed": seed, "captures": len(rows), "wall_time_s": time.perf_counter() - t0, **stamp,
            **summarise(rows), "targets": TARGETS, "rows": rows}
    write_json(out, "gap_cross", data)
    _write_markdown(out, data)
    return data


def headline_rows(data) -> list:
    """[figure, value, target] rows of the cross-prototype study."""
    return [
        ["top-1 (detectable effects)", data["top1_detectable"], "≥ 0.90"],
        ["true effect ranked first by ΔBIC (detectable)", data["ranked_first_detectable"], "—"],
        ["top-1 over the effects the a-priori check calls distinguishable",
         data["top1_distinguishable_a_priori"], "—"],
        ["top-1 over all catalogued effects", data["top1_all_effects"], "—"],
        ["controls answered none", data["control_none_rate"], "≥ 0.90"],
        ["wrong names, all captures", data["wrong_name_rate_all"], "≤ 0.05"],
        ["absorbed effects listed absorbed", data["absorbed_listed_absorbed"], "1.0"],
        ["absorbed effects named wrongly", data["absorbed_wrong_name"], "0"],
        ["outside-catalogue effects named", f"{data['outside_named']} of {data['outside_captures']}", "0"],
        ["diagnose runtime median / max [s]",
         f"{data['runtime_s_median']:.1f} / {data['runtime_s_max']:.1f}" if data["runtime_s_median"] else None,
         "≤ 10"],
    ]


def _write_markdown(out, data):
    from ..studies.report import write_markdown

    g = data["groups"]
    rows = [[k, v["class"], v["captures"], v["top1"], v["ranked_first"], v["wrong_name"], v["none"],
             v["unexplained"], v["listed_absorbed"], v["median_shrink"]] for k, v in g.items()]
    cols = ["effect/op", "class", "n", "top-1", "ranked first", "wrong name", "none", "unexplained",
            "listed absorbed", "median shrink"]
    labels = sorted({v for row in data["confusion"].values() for v in row})
    conf = [[t] + [data["confusion"][t].get(v, 0) for v in labels] for t in data["confusion"]]
    notes = [f"{data['captures']} prototype-B captures (seed {data['seed']}, {data['per_effect']} per effect "
             f"and operation at 0.5–1.5× strength, {data['controls']} controls, {data['outside']} per "
             f"outside-catalogue effect), read back blind from COMTRADE. Wall time "
             f"{data['wall_time_s']:.0f} s.",
             "Status counts: " + ", ".join(f"{k} {v}" for k, v in data["status_counts"].items())]
    write_markdown(out, "gap_cross", "Cross-prototype blind gap study (prototype B, issue 11)",
                   headline_rows(data), ["figure", "value", "target"],
                   sections=[("Per effect and operation", cols, rows),
                             ("Confusion (rows: truth, columns: verdict)", ["truth"] + labels, conf)],
                   notes=notes, digits=3)
