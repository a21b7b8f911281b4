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


# The field nuisance of the Table 9 dataset (issue 22); docs/conditions.md gives each reason.
FIELD_NUISANCE = {
    "trigger_delay_s": (0.005, 0.025),   # motion onset after the record start [s]
    "offset_rad": 0.005,                 # sensor zero offset, ± [rad]
    "gain_spread": 0.01,                 # sensor gain error, ± [-]
    "friction_spread": 0.10,             # resistance torque TOf, ± [-]
    "damping_spread": 0.10,              # buffer damping cb, ± [-]
    "snr_db_range": (40.0, 55.0),        # travel SNR, uniform [dB]
}
# Manufacturing tolerance of a second unit of the same design.
UNIT_TOLERANCE = {"tolerance": 0.03, "alpha0_tolerance_rad": 0.010}  # kO, J2, cb ± [-]; α0 ± [rad]


def classification_spec(seed: int = DEFAULT_SEED, quick: bool = False, *, unit: int = 1,
                        **changes) -> DatasetSpec:
    """The Table 9 dataset of one unit: five opening conditions × 40 captures (quick: 3 × 6),
    every capture with the field nuisance; ``changes`` override single fields (sweeps)."""
    fields = dict(FIELD_NUISANCE, **UNIT_TOLERANCE, unit=unit, operation="open",
                  conditions=3 if quick else 5, per_condition=6 if quick else 40, seed=seed)
    fields.update(changes)
    return DatasetSpec(**fields)


def clean_spec(seed: int = DEFAULT_SEED, quick: bool = False) -> DatasetSpec:
    """The clean Table 9 set of issue 5 (run spread only, aligned trigger): the robustness table."""
    return DatasetSpec(operation="open", conditions=3 if quick else 5,
                       per_condition=6 if quick else 40, seed=seed)


def folds_for(y, seed: int, n_splits: int = 5):
    """One stratified split reused by every method (fewer folds if a class is smaller)."""
    from sklearn.model_selection import StratifiedKFold

    n = min(n_splits, int(np.min(np.bincount(y))))
    return list(StratifiedKFold(n_splits=n, shuffle=True, random_state=seed).split(np.zeros(len(y)), y))


def method_makers(seed: int, quick: bool = False, setting_columns=None) -> dict:
    """name -> ``make() -> classifier``; ``proposed*`` take parameter estimates, the rest raw travel.

    ``setting_columns`` (indices of the parameters the spring setting moves in the design) makes
    ``proposed`` use design-nominal vectors and adds ``proposed_free`` (a nominal per setting for
    every parameter, issue 5's rule) for comparison.
    """
    makers = {
        "proposed": lambda: NearestNominal("within", setting_columns),
        "proposed_global_norm": lambda: NearestNominal("global"),
        "svm": lambda: make_svm(seed, quick),
        "bpnn": lambda: make_bpnn(seed, quick),
        "cnn": lambda: CNN1D(seed, quick),
    }
    if setting_columns is not None:
        makers["proposed_free"] = lambda: NearestNominal("within")
    return makers


def compare_methods(data: dict, *, seed: int, quick: bool = False, methods=METHODS) -> dict:
    """Cross-validate each method on one dataset (see :func:`cross_validate` for the fields).

    Methods whose dependency is missing are reported under ``skipped`` with the reason.
    """
    y = data["condition"]
    folds = folds_for(y, seed)
    est, feat = data["estimates"], data["features"]
    makers = method_makers(seed, quick)
    makers = {name: (makers[name], est if name.startswith("proposed") else feat) for name in makers}
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
