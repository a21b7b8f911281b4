"""The blind check of ``hvcb diagnose`` on withheld effects: ``hvcb study gap --out DIR``.

Captures come from the virtual prototype (fast integrator), each with one catalogued effect at a
realistic strength (uniform in [0.5, 1.5]×REALISTIC) or none (the controls). The state
parameters are drawn around the reference breaker's design values (±10 %, clipped to Table 2's
ranges), the noise is the breaker's usual 0.0015 rad, the travel is quantised to 16 bits and the
vibration channel is recorded. Effects acting on both operations alternate between openings and
closings; the controls are half openings, half closings. Every capture is written as COMTRADE
(``DIR/captures/``) and the diagnoser reads only those files: it is not told the effect.

Reported (``gap.json``, ``gap.md``, ``gap_confusion.png``):

- the confusion matrix (true effect or ``none`` × verdict);
- which effects the study shows distinguishable at realistic strength, per operation (the
  diagnoser's own identifiability check said so on most of that effect's captures on that
  operation) and which absorbed;
- top-1 accuracy over the captures of the distinguishable effects;
- for absorbed effects: how often the effect is listed in ``absorbed`` and how often a wrong
  effect is named (``confident_wrong``);
- the false-alarm rate on the controls (verdict not ``none``);
- the median shrink of the true effect's candidate;
- how often the phase with the largest gap lies in the true effect's region (REGIONS);
- leave-one-effect-out: the true effect removed from the catalogue, the right answer is
  ``unexplained``. Each candidate's fit does not depend on the others, so the verdict without
  the true effect is :func:`service.diagnosis.diagnose.decide` applied to the remaining
  candidates of the same run (identical to rerunning ``diagnose`` with ``effects=`` minus the
  true effect; tests/diagnosis/test_study.py checks this on one capture).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

DEFAULT_SEED = 2026
NOISE_RAD = 0.0015
BITS = 16
STRENGTH_RANGE = (0.5, 1.5)   # × REALISTIC
STATE_SPREAD = 0.10           # ± fraction around the design value


def _effect_jobs(seed: int, n_per_effect: int, n_controls: int):
    from ..mechanics.breaker import TABLE2_RANGES
    from ..prototypes.a import EFFECT_NAMES, OPERATIONS, REALISTIC
    from ..studies.common import load_reference

    breaker = load_reference()
    design = breaker.design_parameters()
    plan = []
    for name in EFFECT_NAMES:
        ops = OPERATIONS[name]
        plan += [(name, ops[i % len(ops)]) for i in range(n_per_effect)]
    plan += [(None, ("open", "close")[i % 2]) for i in range(n_controls)]
    seqs = np.random.SeedSequence(seed).spawn(len(plan))
    jobs = []
    for i, ((name, op), ss) in enumerate(zip(plan, seqs)):
        rng = np.random.default_rng(ss)
        keys = ("AO", "BO", "DO", "EO") if op == "open" else ("AC", "BC", "CC")
        params = {}
        for k in keys:
            lo, hi = TABLE2_RANGES[k]
            params[k] = float(np.clip(design[k] * rng.uniform(1 - STATE_SPREAD, 1 + STATE_SPREAD), lo, hi))
        if op == "close":
            params["DC"] = float(design["DC"])
        factor = float(rng.uniform(*STRENGTH_RANGE)) if name else 0.0
        jobs.append({"index": i, "truth": name or "none", "operation": op, "params": params,
                     "strength": factor * REALISTIC[name] if name else 0.0, "strength_factor": factor,
                     "seed": int(rng.integers(2**31))})
    return jobs


def _run_one(job: dict) -> dict:
    """Make one capture, write it as COMTRADE, and diagnose the file (blind)."""
    from ..acquisition.capture_file import read_capture
    from ..acquisition.comtrade_writer import write_comtrade
    from ..acquisition.synthetic import synthesize_capture
    from ..prototypes.a import REGIONS, Effects, make_prototype_simulator
    from ..studies.common import load_reference
    from .diagnose import DiagnosisError, decide, diagnose

    breaker = load_reference()
    op, truth = job["operation"], job["truth"]
    eff = Effects.only(truth, job["strength"]) if truth != "none" else Effects()
    sim = make_prototype_simulator(breaker, eff, op, method="fast")
    from ..mechanics.trajectory import SimulationError

    redraws = 0
    while True:
        try:
            cap, _ = synthesize_capture(breaker, op, job["params"], rng=np.random.default_rng(job["seed"]),
                                        noise_rad=NOISE_RAD, bits=BITS, simulate=sim)
            break
        except SimulationError:
            # this state cannot complete the operation with the effect (e.g. a closing stalls
            # under a weak spring plus friction): draw the state again, closer to the design
            redraws += 1
            if redraws > 10:
                return {**_public(job), "verdict": "error", "state_redraws": redraws,
                        "error": "the prototype could not complete the operation with this effect"}
            job = dict(job, params=_redraw(job, breaker, redraws))
    name = f"c{job['index']:04d}_{op}"
    cfg = write_comtrade(cap, job["capture_dir"], name)
    # --- blind from here: only the file and the breaker go in ---
    cap_file = read_capture(cfg, travel_channel=breaker.channels["travel"],
                            vibration_channel=breaker.channels["vibration"])
    t0 = time.perf_counter()
    try:
        res = diagnose([cap_file], breaker, op)
    except DiagnosisError as exc:
        return {**_public(job), "file": str(cfg.name), "error": str(exc), "verdict": "error"}
    runtime = time.perf_counter() - t0
    phases = res["gap"]["phases"]
    worst = max(phases, key=lambda p: p["ratio_to_noise"])["name"]
    ident = {v["effect"]: bool(v["distinguishable"]) for v in res["identifiability"]}
    cands = [{k: c[k] for k in ("effect", "delta_bic", "shrink", "holdout_shrink", "distinguishable",
                                "strength", "after_p", "worst_phase_shrink", "worst_phase_share", "phase_shrink_min",
                                "in_region")
              if k in c} for c in res["candidates"]]
    true_c = next((c for c in cands if c["effect"] == truth), None)
    sig_chi2 = res.get("significant_chi2", res["significant_gap"])
    loo = decide(res["candidates"], sig_chi2, exclude=(truth,))[0] if truth != "none" else None
    return {**_public(job), "file": str(cfg.name), "verdict": res["verdict"], "state_redraws": redraws,
            "ambiguous": res.get("ambiguous", []), "significant_gap": res["significant_gap"],
            "significant_chi2": sig_chi2,
            "gap_ratio": res["gap"]["ratio_to_noise"], "worst_phase": worst,
            "worst_in_region": (worst in REGIONS[op][truth]) if truth != "none" else None,
            "true_distinguishable": ident.get(truth) if truth != "none" else None,
            "true_absorbed_reported": (truth in {a["effect"] for a in res["absorbed"]}) if truth != "none" else None,
            "true_shrink": true_c["shrink"] if true_c else None,
            "true_strength_fit": true_c["strength"] if true_c else None,
            "loo_verdict": loo, "candidates": cands, "runtime_s": runtime}


def _redraw(job, breaker, attempt):
    from ..mechanics.breaker import TABLE2_RANGES

    design = breaker.design_parameters()
    rng = np.random.default_rng([job["seed"], attempt])
    spread = STATE_SPREAD / (1 + attempt)
    out = dict(job["params"])
    for k in out:
        if k in TABLE2_RANGES and k != "DC":
            lo, hi = TABLE2_RANGES[k]
            out[k] = float(np.clip(design[k] * rng.uniform(1 - spread, 1 + spread), lo, hi))
    return out


def _public(job):
    return {k: job[k] for k in ("index", "truth", "operation", "params", "strength", "strength_factor", "seed")}


def _frac(xs):
    xs = list(xs)
    return float(np.mean(xs)) if xs else None


def summarise(rows: list, effects) -> dict:
    """The study's figures from the per-capture rows."""
    from ..prototypes.a import EFFECT_NAMES

    truths = [e for e in EFFECT_NAMES if e in effects] + ["none"]
    verdicts = list(EFFECT_NAMES) + ["none", "unexplained", "error"]
    conf = {t: {v: 0 for v in verdicts} for t in truths}
    for r in rows:
        conf[r["truth"]][r["verdict"]] += 1
    eff_rows = [r for r in rows if r["truth"] != "none" and r["verdict"] != "error"]
    per_effect = {}
    for e in truths[:-1]:
        rs = [r for r in eff_rows if r["truth"] == e]
        dist = _frac(r["true_distinguishable"] for r in rs)
        per_effect[e] = {
            "captures": len(rs), "operations": sorted({r["operation"] for r in rs}),
            "distinguishable_fraction": dist,
            "distinguishable": bool(dist is not None and dist >= 0.5),
            "top1": _frac(r["verdict"] == e for r in rs),
            "named_wrong": _frac(r["verdict"] not in (e, "none", "unexplained") for r in rs),
            "none": _frac(r["verdict"] == "none" for r in rs),
            "unexplained": _frac(r["verdict"] == "unexplained" for r in rs),
            "reported_absorbed": _frac(r["true_absorbed_reported"] for r in rs),
            "median_shrink": float(np.median([r["true_shrink"] for r in rs])) if rs else None,
            "worst_phase_in_region": _frac(r["worst_in_region"] for r in rs if r["significant_gap"]),
            "loo_unexplained": _frac(r["loo_verdict"] == "unexplained" for r in rs if r["significant_gap"]),
            "loo_wrong_name": _frac(r["loo_verdict"] not in ("none", "unexplained")
                                    for r in rs if r["significant_gap"]),
            "gap_ratio_median": float(np.median([r["gap_ratio"] for r in rs])) if rs else None,
        }
    # Distinguishability is a property of an effect *on an operation*: friction on the output
    # shaft while opening is not the camshaft friction of a closing.
    groups = {}
    for r in eff_rows:
        groups.setdefault((r["truth"], r["operation"]), []).append(r["true_distinguishable"])
    group_dist = {k: (_frac(v) or 0.0) >= 0.5 for k, v in groups.items()}
    dist_effects = sorted(f"{e}/{op}" for (e, op), d in group_dist.items() if d)
    absorbed_effects = sorted(f"{e}/{op}" for (e, op), d in group_dist.items() if not d)
    d_rows = [r for r in eff_rows if group_dist[(r["truth"], r["operation"])]]
    a_rows = [r for r in eff_rows if not group_dist[(r["truth"], r["operation"])]]
    controls = [r for r in rows if r["truth"] == "none" and r["verdict"] != "error"]
    loo_rows = [r for r in d_rows if r["significant_gap"]]
    return {
        "confusion": conf, "truth_labels": truths, "verdict_labels": verdicts,
        "per_effect": per_effect,
        "distinguishable_effects": dist_effects, "absorbed_effects": absorbed_effects,
        "top1_accuracy_distinguishable": _frac(r["verdict"] == r["truth"] for r in d_rows),
        "top1_accuracy_all_effects": _frac(r["verdict"] == r["truth"] for r in eff_rows),
        "absorbed_reported_absorbed": _frac(r["true_absorbed_reported"] for r in a_rows),
        # The same two figures judged capture by capture, by the diagnoser's own check on each
        # capture (an effect near the top of its strength range can be distinguishable on one
        # capture while its group is mostly absorbed).
        "capture_absorbed_reported_absorbed": _frac(r["true_absorbed_reported"] for r in eff_rows
                                                    if r["true_distinguishable"] is False),
        "capture_top1_distinguishable": _frac(r["verdict"] == r["truth"] for r in eff_rows
                                              if r["true_distinguishable"]),
        "absorbed_confident_wrong": _frac(r["verdict"] not in (r["truth"], "none", "unexplained")
                                          for r in a_rows),
        "confident_wrong_all_effects": _frac(r["verdict"] not in (r["truth"], "none", "unexplained")
                                             for r in eff_rows),
        "control_none_rate": _frac(r["verdict"] == "none" for r in controls),
        "false_alarm_rate": _frac(r["verdict"] != "none" for r in controls),
        "median_shrink_true_effect": (float(np.median([r["true_shrink"] for r in d_rows]))
                                      if d_rows else None),
        "median_shrink_true_effect_all": (float(np.median([r["true_shrink"] for r in eff_rows
                                                           if r["true_shrink"] is not None]))
                                          if eff_rows else None),
        "worst_phase_in_region": _frac(r["worst_in_region"] for r in d_rows if r["significant_gap"]),
        "worst_phase_in_region_all": _frac(r["worst_in_region"] for r in eff_rows if r["significant_gap"]),
        "loo_unexplained_rate": _frac(r["loo_verdict"] == "unexplained" for r in loo_rows),
        "loo_none_rate": _frac(r["loo_verdict"] == "none" for r in loo_rows),
        "loo_wrong_name_rate": _frac(r["loo_verdict"] not in ("none", "unexplained") for r in loo_rows),
        "loo_cases": len(loo_rows),
        "errors": sum(r["verdict"] == "error" for r in rows),
        "runtime_s_median": float(np.median([r["runtime_s"] for r in rows if "runtime_s" in r])) if rows else None,
        "runtime_s_max": float(np.max([r["runtime_s"] for r in rows if "runtime_s" in r])) if rows else None,
    }


TARGETS = {"top1_accuracy_distinguishable": 0.90, "control_none_rate": 0.90,
           "median_shrink_true_effect": 0.70, "loo_unexplained_rate": 0.80,
           "absorbed_confident_wrong": 0.0}


def run_gap_study(out_dir: Path, *, seed: int = DEFAULT_SEED, quick: bool = False, workers: int = 2,
                  n_per_effect: int = 20, n_controls: int = 40, cross: bool = True) -> dict:
    """Run the blind study into ``out_dir``; returns the JSON-able summary (also ``gap.json``).

    With ``cross`` (the default) the cross-prototype study on prototype B's captures
    (:mod:`.cross_study`) runs first and is the headline of ``gap.md``; its full figures are in
    ``gap_cross.json`` / ``gap_cross.md`` and under ``cross_prototype`` in ``gap.json``."""
    from ..prototypes.a import EFFECT_NAMES
    from ..studies.common import pool_map
    from ..studies.report import write_json

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if quick:
        n_per_effect, n_controls = 2, 4
    cap_dir = out / "captures"
    cap_dir.mkdir(exist_ok=True)
    jobs = _effect_jobs(seed, n_per_effect, n_controls)
    for j in jobs:
        j["capture_dir"] = str(cap_dir)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    t0 = time.perf_counter()
    rows = pool_map(_run_one, jobs, max(1, int(workers)))
    wall = time.perf_counter() - t0
    summary = summarise(rows, EFFECT_NAMES)
    cross_data = None
    if cross:
        from .cross_study import run_cross_study

        sizes = {"per_effect": 1, "controls": 4, "outside": 1} if quick else {}
        full = run_cross_study(out, seed=seed, workers=workers, **sizes)
        cross_data = {k: v for k, v in full.items() if k != "rows"}
    data = {"seed": seed, "quick": quick, "workers": workers, "n_per_effect": n_per_effect,
            "n_controls": n_controls, "captures": len(rows), "noise_rad": NOISE_RAD, "bits": BITS,
            "strength_range_x_realistic": list(STRENGTH_RANGE), "state_spread": STATE_SPREAD,
            "wall_time_s": wall, **summary, "targets": TARGETS, "cross_prototype": cross_data, "rows": rows}
    write_json(out, "gap", data)
    _write_markdown(out, data)
    _plot_confusion(out, data)
    return data


def _write_markdown(out, data):
    from ..studies.report import write_markdown

    pe = data["per_effect"]
    rows = [[e, v["operations"] and "/".join(v["operations"]), v["captures"], v["distinguishable_fraction"],
             "distinguishable" if v["distinguishable"] else "absorbed", v["top1"], v["named_wrong"],
             v["none"], v["unexplained"], v["reported_absorbed"], v["median_shrink"],
             v["worst_phase_in_region"], v["loo_unexplained"], v["loo_wrong_name"], v["gap_ratio_median"]]
            for e, v in pe.items()]
    cols = ["effect", "ops", "n", "dist. frac", "class", "top-1", "wrong name", "none", "unexplained",
            "listed absorbed", "median shrink", "worst phase in region", "LOO unexplained",
            "LOO wrong name", "gap/noise (median)"]
    t = data["targets"]
    headline = [
        ["top-1 accuracy (distinguishable effects)", data["top1_accuracy_distinguishable"], "≥ 0.90"],
        ["top-1 accuracy (all effects)", data["top1_accuracy_all_effects"], "—"],
        ["absorbed effects listed as absorbed", data["absorbed_reported_absorbed"], "1.0"],
        ["absorbed effects named wrongly", data["absorbed_confident_wrong"], "0"],
        ["per capture: absorbed (by the check) listed as absorbed",
         data.get("capture_absorbed_reported_absorbed"), "1.0"],
        ["per capture: distinguishable (by the check) named right", data.get("capture_top1_distinguishable"), "—"],
        ["any effect named wrongly", data["confident_wrong_all_effects"], "—"],
        ["controls giving none", data["control_none_rate"], f"≥ {t['control_none_rate']}"],
        ["median shrink, true effect (distinguishable)", data["median_shrink_true_effect"], "≥ 0.70"],
        ["worst phase within the effect's region", data["worst_phase_in_region"], "—"],
        ["leave-one-out → unexplained", data["loo_unexplained_rate"], "≥ 0.80"],
        ["leave-one-out → none", data["loo_none_rate"], "—"],
        ["leave-one-out → wrong name", data["loo_wrong_name_rate"], "—"],
        ["diagnose runtime median [s]", data["runtime_s_median"], "≤ 10"],
        ["diagnose runtime max [s]", data["runtime_s_max"], "≤ 10"],
    ]
    labels = [v for v in data["verdict_labels"] if any(data["confusion"][tl][v] for tl in data["truth_labels"])
              or v in ("none", "unexplained")]
    conf_rows = [[tl] + [data["confusion"][tl][v] for v in labels] for tl in data["truth_labels"]]
    notes = [f"{data['captures']} captures (seed {data['seed']}, {data['n_per_effect']} per effect, "
             f"{data['n_controls']} controls{', quick' if data['quick'] else ''}); strength uniform in "
             f"{data['strength_range_x_realistic']}×REALISTIC; state ±{100 * data['state_spread']:.0f} % "
             f"around the design values within Table 2; noise {data['noise_rad']} rad, {data['bits']}-bit "
             f"travel, vibration channel; COMTRADE files read back blind. Wall time "
             f"{data['wall_time_s']:.0f} s on {data['workers']} workers.",
             "Leave-one-out: the verdict recomputed by `decide()` without the true effect, over the "
             "captures of distinguishable effects with a significant gap."]
    sections = [("Own prototype: figures", ["figure", "value", "target"], headline),
                ("Own prototype: per effect", cols, rows),
                ("Own prototype: confusion matrix (rows: truth, columns: verdict)", ["truth"] + labels, conf_rows)]
    main = headline
    if data.get("cross_prototype"):
        from .cross_study import headline_rows

        main = headline_rows(data["cross_prototype"])
        notes = notes + ["Headline: the cross-prototype study (prototype B, an independently written "
                         "prototype); details in gap_cross.md."]
    write_markdown(out, "gap", "Blind gap-diagnosis study (headline: cross-prototype, prototype B)", main,
                   ["figure", "value", "target"], sections=sections,
                   notes=notes, digits=3)


def _plot_confusion(out, data):
    from ..studies.report import new_figure, save_figure

    labels = [v for v in data["verdict_labels"] if v != "error" or
              any(data["confusion"][tl]["error"] for tl in data["truth_labels"])]
    truths = data["truth_labels"]
    m = np.array([[data["confusion"][tl][v] for v in labels] for tl in truths], float)
    fig, ax = new_figure(figsize=(9, 7))
    ax.imshow(m / np.maximum(m.sum(1, keepdims=True), 1), cmap="Blues", vmin=0, vmax=1)
    for i in range(m.shape[0]):
        for j in range(m.shape[1]):
            if m[i, j]:
                ax.text(j, i, f"{int(m[i, j])}", ha="center", va="center", fontsize=8)
    ax.set_xticks(range(len(labels)), labels, rotation=60, ha="right", fontsize=8)
    ax.set_yticks(range(len(truths)), truths, fontsize=8)
    ax.set_xlabel("verdict")
    ax.set_ylabel("true effect")
    ax.set_title("hvcb diagnose, blind study: confusion matrix")
    save_figure(fig, Path(out) / "gap_confusion.png")
