"""Calibration of the diagnosis's stated probability, measured leave-one-prototype-out.

The map is isotonic regression (pool-adjacent-violators; Zadrozny & Elkan 2002) of "the answer
was right" (:func:`.scoring.right`) on the diagnosis's raw probability of its answer: the only
assumption is that a higher raw probability is never less often right. LOPO: for each
prototype X the map is fitted on the other prototypes' groups only and scores X's, so X's
figure is a held-out one. The map shipped in ``service/diagnosis/calibration.json`` is fitted
on all development prototypes (A, B, C), in the format that ``service.diagnosis.calibration``
loads: {"method", "x": raw p ascending, "y": calibrated, non-decreasing, "fitted_on", "n",
"note"}.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from .scoring import reliability, right, wilson

SHIPPED = Path(__file__).resolve().parents[2] / "diagnosis" / "calibration.json"


def raw_probability(r) -> float:
    """The diagnosis's probability of its answer before any calibration map."""
    return float(r.get("raw_probability", r["answer_probability"]))


def fit_map(rows) -> dict:
    """The isotonic map fitted on ``rows`` (raw probability → fraction right)."""
    from sklearn.isotonic import IsotonicRegression

    if not rows:
        raise ValueError("no diagnosed groups to fit a calibration map on")
    x = np.array([raw_probability(r) for r in rows])
    y = np.array([float(right(r)) for r in rows])
    iso = IsotonicRegression(y_min=0.0, y_max=1.0, increasing=True, out_of_bounds="clip").fit(x, y)
    xs, ys = [float(v) for v in iso.X_thresholds_], [float(v) for v in iso.y_thresholds_]
    # anchored at 0 and 1 with the end values (what clipping gives anyway): the map then has two
    # points even when every raw probability was the same
    if xs[0] > 0.0:
        xs, ys = [0.0] + xs, [ys[0]] + ys
    if xs[-1] < 1.0:
        xs, ys = xs + [1.0], ys + [ys[-1]]
    protos = sorted({r["prototype"] for r in rows})
    return {"method": "isotonic", "x": xs, "y": ys, "fitted_on": protos, "n": int(len(rows)),
            "note": "isotonic regression of 'the answer was right' on the raw probability of the answer, "
                    f"fitted on {len(rows)} diagnosed groups of prototypes {', '.join(p.upper() for p in protos)} "
                    "(hvcb study gap; docs/gap-study.md); linear between the points, clipped outside"}


def apply_map(m: dict, p) -> np.ndarray:
    """The calibrated probability: the map interpolated linearly, clipped at its ends."""
    return np.interp(np.asarray(p, float), m["x"], m["y"])


def lopo(rows, prototypes) -> dict:
    """For each prototype, the map fitted on the others and its reliability on the held-out one."""
    out = {}
    for p in prototypes:
        train = [r for r in rows if r["prototype"] != p and "error" not in r]
        test = [r for r in rows if r["prototype"] == p and "error" not in r]
        if not train or not test:
            out[p] = {"fitted_on": sorted({r["prototype"] for r in train}), "n_test": len(test), "table": None}
            continue
        m = fit_map(train)
        cal = apply_map(m, [raw_probability(r) for r in test])
        hits = [right(r) for r in test]
        hi = cal >= 0.9
        k = int(np.sum(np.asarray(hits)[hi]))
        out[p] = {"fitted_on": m["fitted_on"], "n_train": m["n"], "n_test": len(test),
                  "calibrated": [float(c) for c in cal],
                  "table": reliability(cal, hits),
                  "stated_ge_0_9_right": {"k": k, "n": int(hi.sum()), "fraction": k / hi.sum() if hi.sum() else None,
                                          "wilson95": wilson(k, int(hi.sum()))}}
    return out


def write_shipped(m: dict, path: Path = SHIPPED) -> Path:
    """Write the shipped map (atomically)."""
    if np.any(np.diff(m["x"]) < 0) or np.any(np.diff(m["y"]) < 0):
        raise ValueError("a calibration map must be non-decreasing in x and y")
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(m, indent=1) + "\n")
    os.replace(tmp, path)
    return path
