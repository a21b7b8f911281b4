"""Parameter sets and captures with known truth, shared by the studies.

The studies draw parameter sets in the paper's Table 2 ranges, simulate captures with the
project's own synthetic generator (128 kHz, latch-release shock in the vibration channel) and
add Gaussian white travel noise at a prescribed SNR:

    SNR = 10·log10(mean(θ²) / σ²)   [dB]

with θ the operation's own coordinate (opening angle, or closing θ2) over the valid window
(latch shock to peak) of the noise-free curve. σ is computed per capture. The travel is not
quantised (``bits=None``): at 50 dB the noise σ is about 2 mrad, 40× a 16-bit LSB over 0..π,
so quantisation would change nothing but would blur the noise-free protocol.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from drivers.capture import Capture
from ..acquisition.synthetic import SyntheticTruth, synthesize_capture
from ..mechanics.breaker import CLOSING_PARAMETERS, OPENING_PARAMETERS, TABLE2_RANGES, Breaker
from ..mechanics.closing import simulate_closing
from ..mechanics.coordinates import operation_coordinate
from ..mechanics.opening import simulate_opening

ESTIMATED = OPENING_PARAMETERS + CLOSING_PARAMETERS


def operation_params(params: dict, operation: str) -> dict:
    """The model parameters one operation's simulator takes (closing also needs DC)."""
    names = OPENING_PARAMETERS if operation == "open" else CLOSING_PARAMETERS + ("DC",)
    return {k: float(params[k]) for k in names}


def completes(breaker: Breaker, params: dict, horizon_s: float = 0.2) -> bool:
    """Whether both operations of ``params`` reach their end position (Trajectory.success)."""
    t = np.arange(0.0, horizon_s, 1 / 64000)
    op = simulate_opening(operation_params(params, "open"), t, CO=breaker.CO, alpha0=breaker.alpha0)
    if not (op.success and np.isfinite(op.t_peak)):
        return False
    cl = simulate_closing(operation_params(params, "close"), t, cam=breaker.cam,
                          geometry=breaker.closing_geometry)
    return bool(cl.success and np.isfinite(cl.t_peak))


def draw_parameter_sets(breaker: Breaker, n: int, rng: np.random.Generator,
                        ranges: dict = TABLE2_RANGES, max_draws: int = 100_000):
    """Draw ``n`` parameter sets uniformly in ``ranges``; DC = the set's AO.

    Sets whose closing (or opening) does not complete are rejected and redrawn.

    Returns
    -------
    sets : list of dict
        AO, BO, DO, EO, AC, BC, CC, DC in SI units (s^-2, s^-1, -).
    rejected : int
        How many draws were rejected.
    """
    sets, rejected = [], 0
    for _ in range(max_draws):
        if len(sets) == n:
            break
        p = {k: float(rng.uniform(*ranges[k])) for k in ESTIMATED}
        p["DC"] = p["AO"]
        if completes(breaker, p):
            sets.append(p)
        else:
            rejected += 1
    if len(sets) < n:
        raise RuntimeError(f"only {len(sets)} of {n} parameter sets complete both operations")
    return sets, rejected


def window_slice(truth: SyntheticTruth, fs: float) -> slice:
    """Samples of the valid window (latch shock to peak) of a synthetic capture."""
    return slice(int(np.ceil(truth.t_shock * fs - 1e-9)), int(np.floor(truth.t_peak * fs)) + 1)


def noise_sd_for_snr(theta, snr_db: float) -> float:
    """σ [rad] that gives ``snr_db`` for the window samples ``theta`` [rad]."""
    theta = np.asarray(theta, dtype=float)
    return float(np.sqrt(np.mean(theta**2) / 10 ** (snr_db / 10.0)))


def study_capture(breaker: Breaker, operation: str, params: dict, *, rng: np.random.Generator,
                  snr_db: float | None = None) -> tuple[Capture, SyntheticTruth, float]:
    """A 128 kHz capture with a latch shock, noise-free or with white noise at ``snr_db``.

    Returns the capture, the generator's truth and the travel noise σ [rad] actually added.
    """
    cap, truth = synthesize_capture(breaker, operation, operation_params(params, operation),
                                    rng=rng, noise_rad=0.0, bits=None)
    if snr_db is None:
        return cap, truth, 0.0
    y = operation_coordinate(cap.travel, operation, breaker.stroke)[window_slice(truth, cap.sample_rate)]
    sigma = noise_sd_for_snr(y, snr_db)
    noisy = cap.travel + rng.normal(0.0, sigma, size=cap.travel.size)
    cap = dataclasses.replace(cap, travel=noisy, source=f"{cap.source}@{snr_db:g}dB")
    return cap, dataclasses.replace(truth, noise_rad=sigma), sigma


def error_metrics(true, est) -> dict:
    """R², RMSE, MAE (units of the parameter) and MRE [%] of estimates against truth."""
    true = np.asarray(true, dtype=float)
    est = np.asarray(est, dtype=float)
    ok = np.isfinite(est)
    t, e = true[ok], est[ok]
    if t.size == 0:
        return {"n": 0, "R2": float("nan"), "RMSE": float("nan"), "MAE": float("nan"),
                "MRE_pct": float("nan")}
    err = e - t
    ss_tot = float(np.sum((t - t.mean()) ** 2))
    r2 = 1.0 - float(np.sum(err**2)) / ss_tot if ss_tot > 0 else float("nan")
    return {"n": int(t.size), "R2": r2, "RMSE": float(np.sqrt(np.mean(err**2))),
            "MAE": float(np.mean(np.abs(err))), "MRE_pct": float(100 * np.mean(np.abs(err / t)))}
