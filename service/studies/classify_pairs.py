"""The close–open pair protocols of ``hvcb study classify`` (issue 32): ``cv5_pair`` and
``cross_unit_pair``, the physical ceiling of the single-opening protocols, and the
identifiability table.

Each sample is a closing and an opening of one breaker with one friction and temperature state
(:class:`~.condition_data.DatasetSpec` ``pair``), every field nuisance of the single-opening set
kept. Methods: ``proposed`` (:class:`~.pair_setting.PairSetting` on the fitted AO, BO, BC and CC),
``svm``, ``bpnn`` and ``cnn`` on both raw travel curves end to end, on the same folds.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from .classification_methods import classification_spec
from ..mechanics.spring_setting import steps_per_kO
from .common import load_reference
from .condition_classifiers import NearestNominal, cross_validate, train_test
from .condition_data import STEP_M, build_dataset
from .pair_setting import (PAIR_PARAMETERS, CommissionedPairSetting, PairSetting, friction_direction,
                           identifiability, identifiability_kO, pair_inputs)

PAIR_PROTOCOLS = ("cv5_pair", "cross_unit_pair", "cross_unit_pair_commissioned")
# Acceptance of issues 32 and 39 (the commissioned protocol: issue 39 item 1).
PAIR_TARGET = {"cv5_pair": 0.95, "cross_unit_pair": 0.90, "cross_unit_pair_commissioned": 0.90}
COMMISSIONED = "cross_unit_pair_commissioned"


def reference_index(y) -> int:
    """unit 2's commissioning pair: its first pair at the middle setting (an as-delivered
    setting; fixed before any seed of issue 39 was run). It is scored in no protocol."""
    y = np.asarray(y)
    mid = np.unique(y)[len(np.unique(y)) // 2]
    return int(np.flatnonzero(y == mid)[0])


def pair_specs(seed: int, quick: bool, unit: int, **changes):
    """The opening and the closing spec of one unit's pairs (same draws, two halves)."""
    opening = classification_spec(seed, quick, unit=unit, pair=True, **changes)
    return opening, dataclasses.replace(opening, operation="close")


def build_pairs(seed: int, quick: bool, out_dir: Path, workers: int, **changes) -> dict:
    """unit -> the fitted pairs: ``condition``, ``X`` (n, 4) the proposed inputs
    (:func:`~.pair_setting.pair_inputs`), ``estimates`` (n, 4) the fitted :data:`PAIR_PARAMETERS`, ``features`` (n, 2·FEATURE_POINTS) both raw curves, ``truth``
    (n, 2) the simulator's BO and CC, ``friction`` (n,) the drawn factor, ``failed`` (n,)."""
    out = {}
    for u in (1, 2):
        op, cl = (build_dataset(s, out_dir, workers=workers) for s in pair_specs(seed, quick, u, **changes))
        assert np.array_equal(op["condition"], cl["condition"]) and np.array_equal(op["index"], cl["index"])
        on, cn = [str(n) for n in op["names"]], [str(n) for n in cl["names"]]
        est = {n: op["estimates"][:, on.index(n)] for n in ("AO", "BO")}
        est.update({n: cl["estimates"][:, cn.index(n)] for n in ("BC", "CC")})
        k = list(op["nuisance_names"]).index("friction_factor")
        err = {n: op["stderr"][:, on.index(n)] for n in ("AO", "BO")}
        err.update({n: cl["stderr"][:, cn.index(n)] for n in ("BC", "CC")})
        out[u] = {"condition": op["condition"],
                  "X": pair_inputs(**{n: est[n] for n in PAIR_PARAMETERS}),
                  "estimates": np.column_stack([est[n] for n in PAIR_PARAMETERS]),
                  "stderr": np.column_stack([err[n] for n in PAIR_PARAMETERS]),
                  "features": np.hstack([op["features"], cl["features"]]),
                  "truth": np.column_stack([op["truth"][:, on.index("BO")], cl["truth"][:, cn.index("CC")]]),
                  "friction": op["nuisance"][:, k],
                  "failed": (op["errors"] != "") | (cl["errors"] != "")}
    return out


def run_pair_protocols(pairs: dict, folds, makers: dict, methods, *, desc: str = "pairs") -> dict:
    """protocol -> method -> result on the pairs (``proposed`` on the fitted parameters, the
    baselines on both raw curves), with the single-opening protocols' ``folds``."""
    from ..progress import track

    y1, y2 = pairs[1]["condition"], pairs[2]["condition"]
    res = {p: {} for p in PAIR_PROTOCOLS}
    for proto, m in track([(p, m) for p in PAIR_PROTOCOLS for m in methods], desc=desc, unit="method"):
        key = "X" if m == "proposed" else "features"
        make = PairSetting if m == "proposed" else makers[m]
        t0 = time.perf_counter()
        if proto == "cv5_pair":
            r = cross_validate(make, pairs[1][key], y1, folds)
            sizes = np.array([len(test) for _, test in folds])
            r["accuracy"] = float(np.sum(np.array(r["fold_accuracy"]) * sizes) / sizes.sum())
        elif proto == COMMISSIONED:  # unit 2's one reference pair is known; scored on the rest
            ref = reference_index(y2)
            rest = np.arange(y2.size) != ref
            X2 = pairs[2][key]
            if m == "proposed":
                r = train_test(lambda x=X2[ref], k=y2[ref]: CommissionedPairSetting(x, k), pairs[1][key], y1,
                               X2[rest], y2[rest])
            else:  # the baselines train on unit 1 and the same reference pair
                r = train_test(make, np.vstack([pairs[1][key], X2[ref:ref + 1]]), np.append(y1, y2[ref]),
                               X2[rest], y2[rest])
        else:
            r = train_test(make, pairs[1][key], y1, pairs[2][key], y2)
        r["runtime_s"] = time.perf_counter() - t0
        res[proto][m] = r
    return res


def setting_inference(pairs: dict, kappa: float | None = None) -> dict:
    """The proposed estimator trained on unit 1 and read on unit 2: its stated sd [steps], the
    scatter and bias of its continuous setting about the true one, and of its friction factor
    (relative to unit 1's mean) about the drawn one, on each unit."""
    y1, y2 = pairs[1]["condition"], pairs[2]["condition"]
    m = PairSetting(friction_direction(load_reference())).fit(pairs[1]["X"], y1)
    out = {"stated_sd_steps": m.sd_steps_, "parameters": list(PAIR_PARAMETERS)}
    f_mean = np.mean(pairs[1]["friction"])
    for u, y in ((1, y1), (2, y2)):
        k, _ = m.infer(pairs[u]["X"])
        ok = np.isfinite(k)
        e = (k - y)[ok]
        ef = (m.friction(pairs[u]["X"]) - (pairs[u]["friction"] - f_mean))[ok]
        out[f"unit{u}"] = {"bias_steps": float(np.mean(e)), "sd_steps": float(np.std(e, ddof=1)),
                           "max_abs_steps": float(np.max(np.abs(e))),
                           "friction_bias": float(np.mean(ef)), "friction_sd": float(np.std(ef, ddof=1))}
    # Unit 2 anchored by its commissioning pair (reference_index): the offset is its kO.
    ref = reference_index(y2)
    rest = np.arange(y2.size) != ref
    c = CommissionedPairSetting(pairs[2]["X"][ref], y2[ref]).fit(pairs[1]["X"], y1)
    k2, sd2 = c.infer(pairs[2]["X"])
    e2 = (k2 - y2)[rest & np.isfinite(k2)]
    out["unit2_commissioned"] = {"offset_steps": c.offset_, "stated_sd_steps": float(sd2[0]),
                                 "bias_steps": float(np.mean(e2)), "sd_steps": float(np.std(e2, ddof=1)),
                                 "max_abs_steps": float(np.max(np.abs(e2))),
                                 "coverage_95": float(np.mean(np.abs(e2) <= 1.959964 * sd2[0]))}
    out["physical"] = physical_reading(pairs, ref)
    out["kO_from_AO"] = kO_from_AO(pairs, kappa)
    out["note"] = ("unit 1 is the training set (in-sample); unit 2 is never seen, except by its one "
                   "commissioning pair (reference_index) in unit2_commissioned and physical")
    return out


def physical_reading(pairs: dict, ref: int) -> dict:
    """The operation page's estimator (:func:`~service.mechanics.spring_setting.pair_reading`,
    no training: the design's torques and the fits' own standard errors), on the simulated
    pairs: unit 1 from the design seat (its bias is the fits' bias plus nothing of kO: unit 1
    is the design), and unit 2 relative to its commissioning pair, with the accuracy of the
    nearest setting and the coverage of the stated 95 % interval."""
    from ..mechanics.spring_setting import pair_reading, setting

    base = load_reference()
    j = {n: PAIR_PARAMETERS.index(n) for n in PAIR_PARAMETERS}

    def reads(u):
        d = pairs[u]
        return [pair_reading(base, *(d["estimates"][i, j[n]] for n in ("BO", "BC", "CC")),
                             sd={n: d["stderr"][i, j[n]] for n in ("BO", "BC", "CC")})
                for i in range(d["condition"].size)]

    out = {}
    r1 = reads(1)
    e1 = np.array([r["steps"] for r in r1]) - pairs[1]["condition"]
    ok1 = np.isfinite(e1)
    out["unit1_design_seat"] = {"bias_steps": float(np.mean(e1[ok1])), "sd_steps": float(np.std(e1[ok1], ddof=1)),
                                "median_stated_sd_steps": float(np.nanmedian([r["sd_steps"] for r in r1]))}
    y2 = pairs[2]["condition"]
    r2 = reads(2)
    reference = dict(r2[ref], known_steps=float(y2[ref]))
    got = [setting(r, base, reference=reference) for i, r in enumerate(r2) if i != ref]
    y = np.delete(y2, ref)
    k = np.array([g["steps"] for g in got])
    ok = np.isfinite(k)
    inside = np.array([g["ci95"][0] <= t <= g["ci95"][1] for g, t in zip(got, y)])
    out["unit2_commissioned"] = {
        "accuracy": float(np.mean(np.clip(np.rint(np.nan_to_num(k, nan=-9)), y.min(), y.max()) == y)),
        "bias_steps": float(np.mean((k - y)[ok])), "sd_steps": float(np.std((k - y)[ok], ddof=1)),
        "median_stated_sd_steps": float(np.median([g["sd_steps"] for g in got])),
        "coverage_95": float(np.mean(inside[ok])), "n": int(ok.sum())}
    return out


def kO_from_AO(pairs: dict, kappa: float | None) -> dict:
    """The unit's spring rate read from its own unlabelled pairs: AO·BC = kO·rO²/J1 (J1 is the
    closing side's, not in the unit tolerance), the median over unit 2's pairs over unit 1's,
    against the drawn κ. The Fisher information says it suffices; this measures its bias."""
    j, b = PAIR_PARAMETERS.index("AO"), PAIR_PARAMETERS.index("BC")
    med = {u: float(np.nanmedian(pairs[u]["estimates"][:, j] * pairs[u]["estimates"][:, b])) for u in (1, 2)}
    ratio = med[2] / med[1]
    return {"kappa_read": ratio, "kappa_drawn": kappa,
            "error_percent": None if kappa is None else 100.0 * (ratio - kappa),
            "error_steps": None if kappa is None else (ratio - kappa) * steps_per_kO(load_reference())}


def ceilings(single: dict, pairs: dict, folds) -> dict:
    """What the simulator's true values allow: nearest nominal on the true BO (one opening,
    the 48.5 % of issue 32) and the pair rule on the true (BO, CC), both protocols each."""
    out = {}
    if single is None:  # a pairs-only run: the pairs' openings are single openings of that state
        single = {u: {"condition": pairs[u]["condition"], "truth": pairs[u]["truth"], "bo_column": 0}
                  for u in pairs}
        out["single_opening_source"] = "the openings of the pair set (a pairs-only run)"
    for name, data, make, x in (
            ("single_opening_true_BO", single, NearestNominal, lambda d: d["truth"][:, [d["bo_column"]]]),
            ("pair_true_BO_CC", pairs, PairSetting, lambda d: d["truth"])):
        y1, y2 = data[1]["condition"], data[2]["condition"]
        cv = cross_validate(make, x(data[1]), y1, folds)
        sizes = np.array([len(test) for _, test in folds])
        out[name] = {"cv5": float(np.sum(np.array(cv["fold_accuracy"]) * sizes) / sizes.sum()),
                     "cross_unit": train_test(make, x(data[1]), y1, x(data[2]), y2)["accuracy"]}
    return out


def identifiability_table(pairs: dict) -> dict:
    """:func:`~.pair_setting.identifiability` with the fits' own scatter on unit 1: the sd of
    the fitted BO and CC about a least-squares plane in (setting, drawn friction factor)."""
    d = pairs[1]
    ok = ~d["failed"]
    A = np.column_stack([np.ones(ok.sum()), d["condition"][ok], d["friction"][ok]])
    sd = {}
    for name in ("BO", "CC"):
        v = d["estimates"][ok, PAIR_PARAMETERS.index(name)]
        coef, *_ = np.linalg.lstsq(A, v, rcond=None)
        sd[name] = float(np.std(v - A @ coef, ddof=3))
    base = load_reference()
    out = identifiability(base, sd, base.kO * STEP_M * base.rO)
    resid = []
    for name in ("AO", "BO", "CC"):
        v = d["estimates"][ok, PAIR_PARAMETERS.index(name)]
        coef, *_ = np.linalg.lstsq(A, v, rcond=None)
        resid.append(v - A @ coef)
    cov = np.cov(np.array(resid), ddof=3)
    out["kO_free"] = identifiability_kO(base, cov, base.kO * STEP_M * base.rO, n_pairs=int(ok.sum()))
    out["kO_free"]["fit_covariance"] = {"order": ["AO", "BO", "CC"], "cov": cov.tolist()}
    return out


def identifiability_kO_section(ident: dict) -> tuple:
    """The markdown section of :func:`~.pair_setting.identifiability_kO`."""
    k = ident["kO_free"]
    rows = []
    for name, r in k["sets"].items():
        if r["rank"] < 3:
            rows.append([name, r["rank"], "∞", "—", "—", r["unseen"]])
        else:
            rows.append([name, r["rank"], f"{r['condition_number']:.3g}", f"{100 * r['sd_kappa_one_pair']:.2f} %",
                         f"{100 * r['sd_kappa_unit']:.3f} % ({k['n_pairs']} pairs)",
                         f"setting sd {r['sd_steps_kappa_from_unit']:.3f} steps (if AO had no bias)"])
    c = k["commissioned"]
    rows.append(["pair + commissioning pair", 3, "—", "—", "known offset",
                 f"setting sd {c['sd_steps']:.3f} steps"])
    return (f"identifiability with the unit's spring rate free: unknowns P, f, κ = kO/kO_design "
            f"(Cramér–Rao from the fits' covariance of AO, BO, CC on unit 1; +1 % of kO = "
            f"{k['steps_per_kO_percent']:+.2f} steps)",
            ["observations", "rank", "condition number", "sd κ, one pair", "sd κ, the unit", "setting"], rows)
