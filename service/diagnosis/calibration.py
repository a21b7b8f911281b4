"""The map from the evidence's raw answer probability to a calibrated one.

``calibration.json`` beside this module (written by the study, service/studies: leave-one-
prototype-out isotonic regression) holds {"method", "x": raw p ascending, "y": calibrated p
non-decreasing, "fitted_on": [prototypes], "n", "note"}. Without it the map is the identity.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

import numpy as np

PATH = Path(__file__).with_name("calibration.json")


def load(path: str | None = None) -> dict | None:
    """The calibration table, checked; None when the file is absent."""
    p = Path(path) if path else PATH
    if not p.exists():
        return None
    return _read(str(p), p.stat().st_mtime_ns)


@lru_cache(maxsize=4)
def _read(path: str, _mtime_ns: int) -> dict:
    p = Path(path)
    try:
        c = json.loads(p.read_text(encoding="utf-8"))
        x, y = np.asarray(c["x"], float), np.asarray(c["y"], float)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{p}: not a calibration table ({exc})") from None
    if x.size < 2 or x.size != y.size or np.any(np.diff(x) < 0) or np.any(np.diff(y) < 0) \
            or np.any((y < 0) | (y > 1)) or np.any((x < 0) | (x > 1)):
        raise ValueError(f"{p}: x must ascend and y must not decrease, both in [0, 1], of one length ≥ 2")
    return {**c, "x": x, "y": y}


def calibrate(p_raw: float, path: str | None = None) -> tuple[float, str]:
    """(calibrated probability, method) of a raw answer probability."""
    c = load(path)
    if c is None:
        return float(p_raw), "identity"
    return float(np.interp(p_raw, c["x"], c["y"])), str(c.get("method", "isotonic"))


# The share of probability that the calibration takes from the answer without saying which
# alternative it belongs to (see ``renormalise``).
UNATTRIBUTED = "unattributed"


def renormalise(probabilities: dict, answer: str, p_answer: float) -> dict:
    """``probabilities`` with the answer's set to its calibrated ``p_answer``: one table, one story.

    When the calibration raises the answer, the others shrink in proportion. When it lowers it,
    the map says only how often such an answer is wrong, not which alternative is right, so no
    alternative gains: each keeps its evidence probability, capped at ``p_answer`` (the map would
    state no more for it as an answer), and the rest is listed as ``unattributed``. The answer
    stays the most probable row, and a rival never leads on a share the evidence did not give it.
    """
    raw = float(probabilities[answer])
    if p_answer >= raw:
        rest = 1.0 - raw
        n_other = max(len(probabilities) - 1, 1)
        return {k: float(p_answer) if k == answer else
                (float(p * (1.0 - p_answer) / rest) if rest > 0 else (1.0 - p_answer) / n_other)
                for k, p in probabilities.items()}
    out = {k: float(p_answer) if k == answer else float(min(p, p_answer)) for k, p in probabilities.items()}
    out[UNATTRIBUTED] = max(1.0 - sum(out.values()), 0.0)
    return out
