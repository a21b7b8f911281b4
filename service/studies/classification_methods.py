"""The methods that Table 9 compares, and the shared dataset spec and folds.

Imported by both the classification study (:mod:`.classify`) and the robustness table
(:mod:`.robustness`), so neither imports the other.
"""

from __future__ import annotations

import time

import numpy as np

from .condition_classifiers import NearestNominal, cross_validate, make_bpnn, make_svm
from .condition_cnn import CNN1D, torch_available
from .condition_data import DatasetSpec

PAPER_ACCURACY = {"proposed": 0.983, "svm": 0.950, "bpnn": 0.933, "cnn": 0.950}
METHODS = ("proposed", "svm", "bpnn", "cnn")
DEFAULT_SEED = 2026


def classification_spec(seed: int = DEFAULT_SEED, quick: bool = False) -> DatasetSpec:
    """The Table 9 dataset: five opening conditions × 40 captures (quick: 3 × 6)."""
    return DatasetSpec(operation="open", conditions=3 if quick else 5,
                       per_condition=6 if quick else 40, seed=seed)


def folds_for(y, seed: int, n_splits: int = 5):
    """One stratified split reused by every method (fewer folds if a class is smaller)."""
    from sklearn.model_selection import StratifiedKFold

    n = min(n_splits, int(np.min(np.bincount(y))))
    return list(StratifiedKFold(n_splits=n, shuffle=True, random_state=seed).split(np.zeros(len(y)), y))


def compare_methods(data: dict, *, seed: int, quick: bool = False, methods=METHODS) -> dict:
    """Cross-validate each method on one dataset (see :func:`cross_validate` for the fields).

    Methods whose dependency is missing are reported under ``skipped`` with the reason.
    """
    y = data["condition"]
    folds = folds_for(y, seed)
    est, feat = data["estimates"], data["features"]
    makers = {
        "proposed": (lambda: NearestNominal("within"), est),
        "proposed_global_norm": (lambda: NearestNominal("global"), est),
        "svm": (lambda: make_svm(seed, quick), feat),
        "bpnn": (lambda: make_bpnn(seed, quick), feat),
        "cnn": (lambda: CNN1D(seed, quick), feat),
    }
    out, skipped = {}, {}
    for name in list(methods) + (["proposed_global_norm"] if "proposed" in methods else []):
        if name == "cnn":
            ok, why = torch_available()
            if not ok:
                skipped[name] = why
                continue
        make, X = makers[name]
        t0 = time.perf_counter()
        out[name] = cross_validate(make, X, y, folds)
        out[name]["runtime_s"] = time.perf_counter() - t0
    return {"methods": out, "skipped": skipped, "folds": len(folds),
            "fit_failures": int(np.sum(~np.all(np.isfinite(est), axis=1)))}
