"""The fitted curve of a stored fit, for the page and the API."""

from __future__ import annotations

import numpy as np

from service.estimation.result import fitted_travel


def fit_curve(fit, t: np.ndarray, breaker) -> tuple[np.ndarray, np.ndarray] | None:
    """(times [s], fitted travel [rad]) of a finished fit, or None.

    Fits stored before the curve was dropped from the database keep theirs; every other fit is
    rebuilt from its parameters at the times ``t`` (the capture's, or its preview's).
    """
    if fit is None or fit.status != "done" or not fit.parameters:
        return None
    if fit.curve:
        return np.asarray(fit.curve["t"], float), np.asarray(fit.curve["fitted"], float)
    if fit.window_start_s is None or fit.onset_delay_s is None:
        return None
    try:
        result = getattr(fit, "result", None) or {}
        structure = result.get("structure") or {}
        fv = fitted_travel(fit.kind, fit.parameters, fit.window_start_s, fit.onset_delay_s, t, breaker,
                           dc_used=fit.dc_used, alpha0=(structure.get("alpha0") or {}).get("value"),
                           co=(structure.get("CO") or {}).get("value"),
                           zero_rad=float(result.get("zero_rad") or 0.0))
    except (KeyError, TypeError, ValueError):  # a fit of another model version: nothing to draw
        return None
    return np.asarray(t, float), fv
