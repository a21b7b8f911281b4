"""The gap study's outputs: ``gap_groups.json`` (rows and figures per prototype),
``gap_calibration.json`` (the stated and the LOPO-calibrated reliability tables, the map fitted
on every development prototype) and ``gap.md`` (the tables)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from .calibration import apply_map, fit_map, lopo, raw_probability
from .scoring import DEVELOPMENT, TARGETS, meets, reliability, right, score

LABELS = {"top1_detectable": "top-1 on detectable", "top1_detectable_1000": "top-1 on oracle Δχ² ≥ 1,000", "none_on_healthy": "healthy → none",
          "wrong_names": "wrong names", "two_effect_both": "two effects: both",
          "outside_unexplained": "outside → unexplained", "stated_ge_0_9_right": "right when stated ≥ 0.9",
          "undetectable_none": "undetectable → none",
          "undetectable_none_absorbed_listed": "undetectable → none, effect in absorbed",
          "undetectable_none_absorbed": "undetectable → none, absorbed, bias agrees"}


def summarise(out: Path, rows, meta, *, ship_calibration: bool = False) -> dict:
    """Score the rows, write the files, return the figures."""
    protos = meta["prototypes"]
    figures = {p: score([r for r in rows if r["prototype"] == p]) for p in protos}
    ok = [r for r in rows if "error" not in r]
    stated = {p: reliability([r["answer_probability"] for r in ok if r["prototype"] == p],
                             [right(r) for r in ok if r["prototype"] == p]) for p in protos}
    dev = [p for p in protos if p in DEVELOPMENT]
    held = lopo([r for r in ok if r["prototype"] in dev], dev) if len(dev) > 1 else {}
    full = fit_map([r for r in ok if r["prototype"] in dev]) if any(r["prototype"] in dev for r in ok) else None
    # prototypes outside the development set (D) are scored with the map of all development ones
    for p in protos:
        if p not in dev and full is not None:
            mine = [r for r in ok if r["prototype"] == p]
            cal = apply_map(full, [raw_probability(r) for r in mine])
            held[p] = {"fitted_on": full["fitted_on"], "n_test": len(mine),
                       "table": reliability(cal, [right(r) for r in mine])}
    cal = {"stated": stated, "lopo": held, "map_all_development": full}
    _write(out / "gap_groups.json", {**meta, "per_prototype": figures, "rows": rows})
    _write(out / "gap_calibration.json", {**meta, **cal})
    (out / "gap.md").write_text(markdown(figures, cal, meta))
    # ``ship_calibration`` is kept for the callers; nothing is shipped from here any more: the
    # diagnosis's probabilities are the learnt scorer's (bench/gap_scorer.py ships it, issue 48)
    return {**meta, "per_prototype": figures, "calibration": cal}


def _write(path: Path, data) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float) + "\n")
    os.replace(tmp, path)


def cell(x: dict) -> str:
    if x is None or not x.get("n"):
        return "–"
    lo, hi = x["wilson95"]
    return f"{x['k']}/{x['n']} ({100 * x['fraction']:.0f} %; {100 * lo:.0f}–{100 * hi:.0f})"


def _table_row(label, table) -> str:
    cells = ["–" if not b["n"] else f"{b['fraction_right']:.2f} (n={b['n']}; {b['wilson95'][0]:.2f}–{b['wilson95'][1]:.2f})"
             for b in table]
    return f"| {label} | " + " | ".join(cells) + " |"


def markdown(figures, cal, meta) -> str:
    protos = meta["prototypes"]
    keys = list(LABELS)
    lines = [f"# Gap study (seed {meta['seed']}, sizes {meta['sizes']})", "",
             "k/n (per cent; Wilson 95 % interval in per cent). ✓/✗: the Acceptance's target.", "",
             "| figure | target | " + " | ".join(p.upper() for p in protos) + " |",
             "|---|---|" + "---|" * len(protos)]
    for k in keys:
        t = TARGETS.get(k)
        tgt = f"{t[0]} {100 * t[1]:.0f} %" if t else "–"
        cells = []
        for p in protos:
            c = cell(figures[p][k])
            ok = meets(figures[p][k], t) if t else None
            cells.append(c + ("" if ok is None else " ✓" if ok else " ✗"))
        lines.append(f"| {LABELS[k]} | {tgt} | " + " | ".join(cells) + " |")
    lines.append("| oracle: detectable single-effect groups | – | " + " | ".join(
        f"{figures[p]['oracle_detectable']['k']}/{figures[p]['oracle_detectable']['n']}" for p in protos) + " |")
    lines.append("| errors (refused) | – | " + " | ".join(str(figures[p]["errors"]) for p in protos) + " |")
    lines.append("| stated gap reduction within ×1.5 of the oracle's (correctly named) | – | " + " | ".join(
        cell(figures[p]["shrink_ratio"]) + (f", median {figures[p]['shrink_ratio']['median']:.2f}"
                                            if figures[p]["shrink_ratio"].get("median") is not None else "")
        for p in protos) + " |")
    bins = cal["stated"][protos[0]] if protos else []
    head = "| | " + " | ".join(f"{b['from']:.2f}–{b['to']:.2f}" for b in bins) + " |"
    lines += ["", "Reliability: probability of the answer vs fraction right (n; Wilson 95 %).", "",
              head, "|---|" + "---|" * len(bins)]
    for p in protos:
        lines.append(_table_row(f"{p.upper()} stated", cal["stated"][p]))
    for p, v in cal["lopo"].items():
        if v.get("table"):
            lines.append(_table_row(f"{p.upper()} calibrated on {'+'.join(q.upper() for q in v['fitted_on'])}",
                                    v["table"]))
    return "\n".join(lines) + "\n"
