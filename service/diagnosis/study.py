"""``hvcb study gap``: the blind group study of the breaker-level diagnosis (issue 20).

Per prototype (A: own; B: independently written; C: blind, when installed), groups of captures
of one breaker under varying conditions are written as COMTRADE (``<out>/<proto>/``) by the
prototype's ``groups.write_groups``; each group is diagnosed jointly from the files alone, and
its first capture also alone (the single-capture figures). The manifest is read afterwards.

Outputs: ``gap_groups.json`` (per prototype: top-1 over detectable effects, ``none`` on
healthy, wrong names over all groups, absorbed listed with bias, outside → unexplained, two-effect
results), ``gap_calibration.json`` (stated probability bins vs fraction right, per prototype and
pooled), ``gap_single.json`` and ``gap_single.png``, and ``gap.md`` with the tables.

A group is **detectable** when its joint gap matters (decision.MILD: the reduced model's misfit
is at least the sd of one block mean); top-1 is counted there and, for reference, over all
single-effect groups.
"""

from __future__ import annotations

import importlib
import json
import os
import time
from pathlib import Path

import numpy as np

DEFAULT_SEED = 2026
BINS = (0.0, 0.5, 0.7, 0.9, 0.99, 1.0000001)
SIZES = {"per_effect": 4, "controls": 6, "two_effect": 4, "outside": 2, "captures_per_group": 5}
QUICK = {"per_effect": 1, "controls": 2, "two_effect": 1, "outside": 1, "captures_per_group": 3}


def _diagnose_job(job: dict) -> dict:
    """Diagnose one group (or one capture) from its files, blind."""
    from ..acquisition.capture_file import read_capture
    from ..studies.common import load_reference
    from .diagnose import DiagnosisError, diagnose

    breaker = load_reference()
    caps = [read_capture(str(Path(job["dir"]) / (s if s.endswith(".cfg") else f"{s}.cfg")), travel_channel=breaker.channels["travel"],
                         vibration_channel=breaker.channels["vibration"]) for s in job["stems"]]
    t0 = time.process_time()
    try:
        r = diagnose(caps, breaker, job["operation"], next_measurements=False)
    except DiagnosisError as exc:
        return {**job, "error": str(exc)}
    keep = ("status", "effects", "probabilities", "rivals", "absorbed", "gap", "answer",
            "answer_probability", "raw_probability", "materiality", "discrepancy")
    return {**job, **{k: r[k] for k in keep}, "cpu_s": time.process_time() - t0}


def _truth_name(effects: dict, outside: bool) -> str:
    if outside:
        return "outside_catalogue"
    return "+".join(sorted(effects)) if effects else "none"


def _answer_name(row) -> str:
    """The answer whose probability is stated: the most probable hypothesis, its mild effects
    left out (``answer`` in the result)."""
    return row["answer"]


MILD = 0.25   # the old size rule σ/√16 (gone from the decision), this study's "detectable" until the oracle


def score(rows) -> dict:
    """The figures of one set of diagnosed groups (or single captures)."""
    ok = [r for r in rows if "error" not in r]
    singles = [r for r in ok if len(r["truth"]) == 1 and not r["outside"]]
    detectable = [r for r in singles if r["gap"]["gap_sigma"] >= MILD]
    healthy = [r for r in ok if not r["truth"] and not r["outside"]]
    two = [r for r in ok if len(r["truth"]) == 2]
    outside = [r for r in ok if r["outside"]]

    def top1(r):
        return r["status"] == "named" and set(r["effects"]) == set(r["truth"])

    def wrong(r):
        return any(e not in r["truth"] for e in r["effects"])

    def both(r):
        if r["status"] == "named" and set(r["effects"]) == set(r["truth"]):
            return True
        names = set()
        for rv in r["rivals"]:
            names |= set(rv["effect"].split("+"))
        return r["status"] == "ambiguous" and set(r["truth"]) <= names

    def absorbed_listed(r):
        return any(a["effect"] in r["truth"] for a in r["absorbed"])

    def frac(xs, f):
        return {"n": len(xs), "k": int(sum(bool(f(x)) for x in xs)),
                "fraction": float(np.mean([bool(f(x)) for x in xs])) if xs else None}

    return {
        "groups": len(rows), "errors": len(rows) - len(ok),
        "top1_detectable": frac(detectable, top1), "top1_all_effect_groups": frac(singles, top1),
        "none_on_healthy": frac(healthy, lambda r: r["status"] == "none"),
        "wrong_names": frac(ok, wrong),
        "absorbed_listed": frac([r for r in singles if r not in detectable], absorbed_listed),
        "outside_unexplained": frac(outside, lambda r: r["status"] == "unexplained"),
        "two_effect_both": frac(two, both),
        "status_counts": {s: sum(r["status"] == s for r in ok) for s in ("none", "named", "ambiguous", "unexplained")},
        "cpu_s_median": float(np.median([r["cpu_s"] for r in ok])) if ok else None,
    }


def _right(r, strict: bool) -> bool:
    """The answer is the truth; not ``strict``: ``none`` is also right when the group's gap is
    below what matters (decision.MILD) — it says "no effect that matters", and there is none."""

    if _answer_name(r) == _truth_name(r["truth"], r["outside"]):
        return True
    return (not strict) and _answer_name(r) == "none" and r["gap"]["gap_sigma"] < MILD


def calibration(rows, strict: bool = False) -> dict:
    """Stated probability (of the answer given or leading: the most probable answer, mild
    effects left out) in bins vs the fraction right (:func:`_right`)."""
    ok = [r for r in rows if "error" not in r]
    out = []
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        sel = [r for r in ok if lo <= r["answer_probability"] < hi]
        out.append({"stated_from": lo, "stated_to": min(hi, 1.0), "n": len(sel),
                    "mean_stated": float(np.mean([r["answer_probability"] for r in sel])) if sel else None,
                    "fraction_right": float(np.mean([_right(r, strict) for r in sel])) if sel else None})
    hi_sel = [r for r in ok if r["answer_probability"] >= 0.9]
    return {"strict": strict, "bins": out, "stated_ge_0_9": {"n": len(hi_sel), "fraction_right": float(np.mean(
        [_right(r, strict) for r in hi_sel])) if hi_sel else None}}


def summarise(out: Path, rows, meta) -> dict:
    """Score the diagnosed rows and write the JSON files, the figure and ``gap.md``."""
    protos = meta["prototypes"]
    groups = {p: score([r for r in rows if r["prototype"] == p and r["kind"] == "group"]) for p in protos}
    single = {p: score([r for r in rows if r["prototype"] == p and r["kind"] == "single"]) for p in protos}
    cal, strict = {}, {}
    for p in protos + ["pooled"]:
        mine = [r for r in rows if p == "pooled" or r["prototype"] == p]
        cal[p] = {k: calibration([r for r in mine if r["kind"] == k]) for k in ("group", "single")}
        strict[p] = {k: calibration([r for r in mine if r["kind"] == k], True) for k in ("group", "single")}
    _write(out / "gap_groups.json", {**meta, "per_prototype": groups,
                                     "rows": [r for r in rows if r["kind"] == "group"]})
    _write(out / "gap_calibration.json", {**meta, **cal, "strict": strict})
    _write(out / "gap_single.json", {**meta, "per_prototype": single,
                                     "rows": [r for r in rows if r["kind"] == "single"]})
    _plot(out, groups, single)
    (out / "gap.md").write_text(markdown(groups, single, cal, meta, strict))
    return {**meta, "groups": groups, "single": single, "calibration": cal}


def rescore(out_dir) -> dict:
    """Score an earlier run again from its saved rows (no diagnosis is rerun)."""
    out = Path(out_dir)
    g = json.loads((out / "gap_groups.json").read_text())
    s1 = json.loads((out / "gap_single.json").read_text())
    meta = {k: g.get(k) for k in ("seed", "quick", "sizes", "prototypes", "wall_s", "complete")}
    return summarise(out, g["rows"] + s1["rows"], meta)


def _generator(p):
    """The prototype's group generator: ``service.prototypes.<p>.groups`` or the package itself."""
    try:
        return importlib.import_module(f"service.prototypes.{p}.groups")
    except ModuleNotFoundError:
        mod = importlib.import_module(f"service.prototypes.{p}")
        if not hasattr(mod, "write_groups"):
            raise
        return mod


def available_prototypes():
    out = []
    for p in ("a", "b", "c"):
        try:
            _generator(p)
            out.append(p)
        except ModuleNotFoundError:
            pass
    return out


def _groups_of(d: Path, returned):
    """The groups of a written manifest (a dict with ``groups`` or a plain list)."""
    data = json.loads((d / "manifest.json").read_text()) if (d / "manifest.json").exists() else returned
    return data["groups"] if isinstance(data, dict) else data


def run_gap_study(out_dir: Path, *, seed: int = DEFAULT_SEED, quick: bool = False, workers: int = 2,
                  prototypes=None, sizes=None) -> dict:
    """Write the groups of each prototype, diagnose them (worker pool, progress bar), score."""
    from ..studies.common import pool_map

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sizes = dict(sizes or (QUICK if quick else SIZES))
    protos = list(prototypes or available_prototypes())
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    jobs = []
    for p in protos:
        mod = _generator(p)
        d = out / p
        returned = mod.write_groups(d, seed=seed, **sizes)
        for g in _groups_of(d, returned):
            base = {"prototype": p, "dir": str(d), "group": g.get("group", g.get("id")), "operation": g["operation"],
                    "truth": sorted(k for k in g["effects"] if not g["outside_catalogue"]),
                    "outside": bool(g["outside_catalogue"])}
            jobs.append({**base, "kind": "group", "stems": g["stems"]})
            jobs.append({**base, "kind": "single", "stems": g["stems"][:1]})
    t0 = time.perf_counter()
    rows, result = [], None
    # groups first, then single captures, prototype by prototype: the files are rewritten after
    # each batch, so a long run that is stopped keeps what it has finished
    for kind in ("group", "single"):
        for p in protos:
            batch = [j for j in jobs if j["kind"] == kind and j["prototype"] == p]
            rows += pool_map(_diagnose_job, batch, max(1, int(workers)))
            meta = {"seed": seed, "quick": quick, "sizes": sizes, "prototypes": protos,
                    "wall_s": time.perf_counter() - t0, "complete": kind == "single" and p == protos[-1]}
            result = summarise(out, rows, meta)
    return result


def _write(path, data):
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float) + "\n")
    os.replace(tmp, path)


def _f(x):
    if x is None or x["n"] == 0:
        return "–"
    return f"{x['k']}/{x['n']} ({100 * x['fraction']:.0f} %)"


def markdown(groups, single, cal, meta, strict=None) -> str:
    lines = [f"# Gap study (seed {meta['seed']}, sizes {meta['sizes']})", "",
             "| prototype | set | top-1 detectable | top-1 all effect groups | none on healthy | wrong names | "
             "absorbed listed | outside → unexplained | two-effect both |", "|---|---|---|---|---|---|---|---|---|"]
    for p in meta["prototypes"]:
        for label, s in (("groups", groups[p]), ("single", single[p])):
            lines.append(f"| {p.upper()} | {label} | {_f(s['top1_detectable'])} | {_f(s['top1_all_effect_groups'])} | "
                         f"{_f(s['none_on_healthy'])} | {_f(s['wrong_names'])} | {_f(s['absorbed_listed'])} | "
                         f"{_f(s['outside_unexplained'])} | {_f(s['two_effect_both'])} |")
    lines += ["", "Calibration: stated probability of the answer vs fraction right (`strict`: `none` is right "
              "only on healthy breakers; otherwise also when the gap is below MILD)", "",
              "| prototype | " + " | ".join(f"{b['stated_from']:.2f}–{b['stated_to']:.2f}"
                                            for b in cal["pooled"]["group"]["bins"]) + " | stated ≥ 0.9 |",
              "|---|" + "---|" * (len(BINS))]
    for kind in ("group", "single"):
        for label, table in (("", cal), (" strict", strict or {})):
            for p in meta["prototypes"] + ["pooled"]:
                if p not in table:
                    continue
                c = table[p][kind]
                cells = [("–" if b["n"] == 0 else f"{b['fraction_right']:.2f} (n={b['n']})") for b in c["bins"]]
                s9 = c["stated_ge_0_9"]
                last = "–" if not s9["n"] else f"{s9['fraction_right']:.2f} (n={s9['n']})"
                lines.append(f"| {p} {kind}{label} | " + " | ".join(cells) + f" | {last} |")
    return "\n".join(lines) + "\n"


def _plot(out, groups, single):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = ["top1_detectable", "none_on_healthy", "wrong_names", "outside_unexplained"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.5), sharey=True)
    for ax, (label, data) in zip(axes, (("groups", groups), ("single captures", single))):
        for i, p in enumerate(data):
            vals = [data[p][k]["fraction"] or 0.0 for k in keys]
            ax.bar(np.arange(len(keys)) + 0.25 * i, vals, width=0.25, label=p.upper())
        ax.set_xticks(np.arange(len(keys)) + 0.25, [k.replace("_", "\n") for k in keys], fontsize=7)
        ax.set_title(label)
        ax.legend()
    fig.tight_layout()
    fig.savefig(out / "gap_single.png", dpi=100)
    plt.close(fig)
