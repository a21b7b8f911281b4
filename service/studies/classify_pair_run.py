"""``hvcb study classify-pairs``: the close–open pair protocols of Table 9 alone (issue 39).

The same pairs, folds, methods and tables as the pair half of ``hvcb study classify``
(:mod:`.classify_pairs`), without the single-opening set and its friction sweep, so that the
pair protocols can be run at full size on several seeds. The single-opening ceiling is kept:
the nearest-setting rule on the simulator's true BO of the pairs' openings (one opening of
that friction state: the same physics as the single-opening set).

Protocols: ``cv5_pair`` (unit 1, five folds), ``cross_unit_pair`` (trained on unit 1, read on
unit 2, never seen), ``cross_unit_pair_commissioned`` (the same, with unit 2's one commissioning
pair at a known setting; scored on its other pairs).

Writes ``classify.json`` (``pairs_only``: true) and ``classify.md``.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .classification_methods import (
    DEFAULT_SEED,
    METHODS,
    PAPER_ACCURACY,
    classification_spec,
    folds_for,
    method_makers,
)
from .classify_pairs import (
    COMMISSIONED,
    PAIR_PROTOCOLS,
    PAIR_TARGET,
    build_pairs,
    ceilings,
    identifiability_kO_section,
    identifiability_table,
    run_pair_protocols,
    setting_inference,
)
from .common import DEFAULT_WORKERS, load_reference
from .condition_cnn import torch_available
from .condition_data import setting_parameters, unit_breaker
from .report import write_json, write_markdown


def run(out_dir: Path, *, seed: int = DEFAULT_SEED, quick: bool = False, workers: int = DEFAULT_WORKERS,
        per_condition: int | None = None, methods=None) -> dict:
    """Fit the pairs of both units and run the three pair protocols into ``out_dir``.

    ``per_condition``: pairs per setting and unit instead of 40; ``methods``: a subset of
    ``proposed, svm, bpnn, cnn`` (default all that are installed).
    """
    size = {} if per_condition is None else {"per_condition": per_condition}
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    pairs = build_pairs(seed, quick, out_dir, workers, **size)
    t_fits = time.perf_counter() - t0
    y1 = pairs[1]["condition"]
    folds = folds_for(y1, seed)
    spec = classification_spec(seed, quick, unit=1, **size)
    names = list(spec.parameter_names)
    makers = method_makers(seed, quick, setting_columns=[names.index(k) for k in setting_parameters(spec)])
    skipped = {}
    if not torch_available()[0]:
        skipped["cnn"] = torch_available()[1]
    chosen = [m for m in (methods or METHODS) if m not in skipped]
    res = run_pair_protocols(pairs, folds, makers, chosen)
    base = load_reference()
    unit2 = unit_breaker(base, classification_spec(seed, quick, unit=2, **size))
    kappa = unit2.kO / base.kO
    result = {
        "pairs_only": True,
        "protocols": {p: {m: res[p][m]["accuracy"] for m in chosen} for p in PAIR_PROTOCOLS},
        "confusion": {p: {m: res[p][m]["confusion"] for m in chosen} for p in PAIR_PROTOCOLS},
        "cv5_pair_fold_accuracy": {m: res["cv5_pair"][m]["fold_accuracy"] for m in chosen},
        "best_params": {p: {m: res[p][m]["best_params"] for m in chosen if m != "proposed"} for p in PAIR_PROTOCOLS},
        "runtime_s": {p: {m: res[p][m]["runtime_s"] for m in chosen} for p in PAIR_PROTOCOLS},
        "ceiling": ceilings(None, pairs, folds),
        "identifiability": identifiability_table(pairs),
        "setting_inference": setting_inference(pairs, kappa),
        "unit2_constants": {"kO": kappa, "J2": unit2.J2 / base.J2, "cb": unit2.cb / base.cb,
                            "alpha0_rad": unit2.alpha0 - base.alpha0,
                            "note": "drawn truth of unit 2 (ratios to the design; α0 as a difference): "
                                    "recorded here, used by no method"},
        "pair_fit_failures": {f"unit{u}": int(np.sum(pairs[u]["failed"])) for u in pairs},
        "samples": {"unit1": int(y1.size), "unit2": int(pairs[2]["condition"].size)},
        "seed": seed, "quick": quick, "per_condition": spec.per_condition, "folds": len(folds),
        "skipped": skipped, "paper_accuracy": PAPER_ACCURACY, "target": dict(PAIR_TARGET),
        "wall_time_s": {"fits": t_fits, "total": time.perf_counter() - t0},
    }
    result["acceptance"] = {f"{p} proposed >= {100 * t:.1f} %": bool(result["protocols"][p]["proposed"] >= t)
                            for p, t in PAIR_TARGET.items() if "proposed" in result["protocols"][p]}
    _write_tables(out_dir, result)
    write_json(out_dir, "classify", result)
    return result


def _write_tables(out_dir: Path, result: dict) -> None:
    from .classify import identifiability_section

    methods = [m for m in METHODS if m in result["protocols"]["cv5_pair"]]
    rows = [[m] + [100 * result["protocols"][p][m] for p in PAIR_PROTOCOLS] + [100 * PAPER_ACCURACY[m]]
            for m in methods]
    ce = result["ceiling"]
    rows.append(["(ceiling: true BO of one opening)", 100 * ce["single_opening_true_BO"]["cv5"],
                 100 * ce["single_opening_true_BO"]["cross_unit"], None, None])
    rows.append(["(ceiling: true BO and CC)", 100 * ce["pair_true_BO_CC"]["cv5"],
                 100 * ce["pair_true_BO_CC"]["cross_unit"], None, None])
    sections = [identifiability_section(result["identifiability"]),
                identifiability_kO_section(result["identifiability"])]
    for p in PAIR_PROTOCOLS:
        for m in methods:
            c = result["confusion"][p][m]
            sections.append((f"confusion: {p}, {m} (rows true setting, columns predicted)",
                             ["true \\ pred"] + [str(k + 1) for k in range(len(c))],
                             [[i + 1] + row for i, row in enumerate(c)]))
    si = result["setting_inference"]
    u2 = result["unit2_constants"]
    ko = si["kO_from_AO"]
    ph = si["physical"]
    notes = [
        f"Seed {result['seed']}, {result['per_condition']} pairs per setting and unit; failed pair fits: "
        f"unit 1 {result['pair_fit_failures']['unit1']}, unit 2 {result['pair_fit_failures']['unit2']}.",
        f"Unit 2 (drawn, used by no method): kO ×{u2['kO']:.4f}, J2 ×{u2['J2']:.4f}, cb ×{u2['cb']:.4f}, "
        f"α0 {1e3 * u2['alpha0_rad']:+.1f} mrad.",
        f"{COMMISSIONED}: unit 2's commissioning pair (its first at the middle setting) is known; the "
        f"proposed estimate's offset there was {si['unit2_commissioned']['offset_steps']:+.3f} steps; on the "
        f"other pairs bias {si['unit2_commissioned']['bias_steps']:+.3f}, sd {si['unit2_commissioned']['sd_steps']:.3f} "
        f"steps, 95 % coverage {100 * si['unit2_commissioned']['coverage_95']:.0f} %.",
        f"kO from the unit's own AO·BC: read ×{ko['kappa_read']:.4f} against the drawn ×{ko['kappa_drawn']:.4f} "
        f"({ko['error_percent']:+.2f} %, {ko['error_steps']:+.2f} steps).",
        f"The operation page's estimator (design torques, the fits' standard errors) relative to the "
        f"commissioning pair: accuracy {100 * ph['unit2_commissioned']['accuracy']:.1f} %, bias "
        f"{ph['unit2_commissioned']['bias_steps']:+.3f}, sd {ph['unit2_commissioned']['sd_steps']:.3f} steps, "
        f"stated sd (median) {ph['unit2_commissioned']['median_stated_sd_steps']:.3f} steps, 95 % coverage "
        f"{100 * ph['unit2_commissioned']['coverage_95']:.1f} % (n = {ph['unit2_commissioned']['n']}); from the "
        f"design seat on unit 1: bias {ph['unit1_design_seat']['bias_steps']:+.2f} steps.",
        f"Wall time {result['wall_time_s']['total']:.0f} s (fits {result['wall_time_s']['fits']:.0f} s).",
    ]
    write_markdown(out_dir, "classify", "Table 9 from the close–open pair (pair protocols only)", rows,
                   ["method"] + [f"{p} [%]" for p in PAIR_PROTOCOLS] + ["paper Table 9 [%]"],
                   sections=sections, notes=notes)
