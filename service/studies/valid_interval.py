"""Valid-interval curves: captures that hold exactly the paper's valid interval.

A user may hand in only the part of an operation the model describes: from rest (the onset of
motion) to the maximum of the operation's own coordinate, as a CSV ``t_s,travel_rad``. These
curves come from the project's own models (Eq. 11 opening, Eq. 7 closing), with Gaussian white
travel noise at a prescribed SNR over the valid interval (see ``synthetic_sets``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..acquisition.synthetic import operation_travel
from ..mechanics.breaker import Breaker
from ..mechanics.coordinates import operation_coordinate
from .synthetic_sets import noise_sd_for_snr, operation_params


def valid_interval_curve(breaker: Breaker, operation: str, params: dict, *, rng: np.random.Generator,
                         fs: float = 128_000.0, snr_db: float | None = 50.0, cut_before_s: float = 0.0):
    """One operation from rest to its maximum, cut ``cut_before_s`` before it.

    Parameters
    ----------
    params : dict
        Model parameters (AO, BO, DO, EO; AC, BC, CC, DC) [SI].
    fs : float
        Sample rate [Hz].
    snr_db : float or None
        Travel SNR over the valid interval [dB]; None for a noise-free curve.
    cut_before_s : float
        The curve ends this long before the maximum [s] (0: at the maximum).

    Returns
    -------
    t : ndarray
        Sample times from the onset of motion [s].
    travel : ndarray
        Travel [rad from closed].
    t_peak : float
        Time of the maximum [s].
    """
    t_probe = np.arange(0.0, 0.2, 1.0 / fs)
    full, t_peak, _ = operation_travel(breaker, operation, operation_params(params, operation), t_probe)
    if not np.isfinite(t_peak):
        raise ValueError("the simulated operation never reaches its maximum")
    n_valid = int(np.floor(t_peak * fs + 1e-9)) + 1
    n = int(np.floor((t_peak - cut_before_s) * fs + 1e-9)) + 1
    travel = full[:n].copy()
    if snr_db is not None:
        sigma = noise_sd_for_snr(operation_coordinate(full[:n_valid], operation, breaker.stroke), snr_db)
        travel += rng.normal(0.0, sigma, size=n)
    return t_probe[:n].copy(), travel, float(t_peak)


def write_csv(path: str | Path, t, travel) -> Path:
    """Write ``t_s,travel_rad`` [s, rad] as ``hvcb fit`` reads it."""
    path = Path(path)
    rows = "\n".join(f"{a:.9f},{b:.7f}" for a, b in zip(t, travel))
    path.write_text("t_s,travel_rad\n" + rows + "\n")
    return path
