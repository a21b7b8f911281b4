"""A fit's answer as strict JSON: a value that cannot be computed is ``null`` with its reason
beside it (``<key>_reason``), never ``NaN`` or ``Infinity``, which JSON does not have (RFC 8259)
and which strict readers refuse."""

from __future__ import annotations

import math

import numpy as np


def why_not_finite(value: float) -> str:
    if math.isnan(value):
        return "not computable from this record (NaN: a missing or over-range sample, or 0/0, on its path)"
    return f"not finite ({'+' if value > 0 else '-'}∞: a division by zero, e.g. a fitness with an RMSE of 0)"


def finite_tree(obj):
    """``obj`` with every non-finite float replaced by None; in a dict, ``key_reason`` says why
    (unless the dict already gives one). numpy scalars and arrays become plain numbers and lists."""
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            if isinstance(v, (float, np.floating)) and not math.isfinite(float(v)):
                out[k] = None
                if isinstance(k, str):
                    obj_reason = obj.get(f"{k}_reason")
                    out[f"{k}_reason"] = obj_reason or why_not_finite(float(v))
            elif isinstance(k, str) and k.endswith("_reason") and k in out:
                continue  # a reason written for a value replaced above
            else:
                out[k] = finite_tree(v)
        return out
    if isinstance(obj, (list, tuple)):
        return [finite_tree(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return finite_tree(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj
