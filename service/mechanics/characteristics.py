"""Classic travel characteristics, as a breaker analyzer reports them.

All are read off the measured travel [rad from closed] after light smoothing; positions are
given as fractions of the stroke from the operation's starting position.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

from .coordinates import operation_coordinate


def travel_characteristics(t, travel, operation: str, *, stroke: float, t_start: float,
                           alpha0: float | None = None, contact_fraction: float | None = None,
                           speed_zone: tuple = (0.1, 0.6), settle_band: float = 0.02,
                           smooth_s: float = 0.5e-3) -> dict:
    """Operating time, average speed, maximum travel, overtravel, rebound and damping time.

    Parameters
    ----------
    t : array_like
        Sample times [s from the first sample].
    travel : array_like
        Travel [rad from closed].
    operation : {"open", "close"}
    stroke : float
        Open rest angle [rad].
    t_start : float
        Command/latch instant the operating time counts from [s].
    alpha0 : float, optional
        Buffer engagement angle [rad]; the damping time of an opening counts from it.
    contact_fraction : float, optional
        Contact separation (opening, default 0.2) or touch (closing, default 0.8) position as a
        fraction of the stroke.
    speed_zone : tuple
        Fractions of the stroke between which the average speed is taken.
    settle_band : float
        Fraction of the stroke within which the motion counts as settled.

    Returns
    -------
    dict
        operating_time_s [s], average_speed_rad_s [rad/s], max_travel_rad [rad],
        overtravel_rad [rad], rebound_rad [rad], damping_time_s [s] (NaN when undefined).
    """
    t = np.asarray(t, dtype=float)
    y = operation_coordinate(np.asarray(travel, dtype=float), operation, stroke)
    fs = 1.0 / (t[1] - t[0])
    n = max(int(smooth_s * fs), 1)
    ys = uniform_filter1d(y, n, mode="nearest")
    start = ys[t <= t_start].mean() if np.any(t <= t_start) else ys[0]
    if contact_fraction is None:
        contact_fraction = 0.2 if operation == "open" else 0.8
    nan = float("nan")

    def crossing(level):
        after = np.nonzero((t >= t_start) & (ys >= start + level * stroke))[0]
        return float(t[after[0]]) if after.size else nan

    t_contact = crossing(contact_fraction)
    t_lo, t_hi = crossing(speed_zone[0]), crossing(speed_zone[1])
    speed = (speed_zone[1] - speed_zone[0]) * stroke / (t_hi - t_lo) if t_hi > t_lo else nan
    i_peak = int(np.argmax(ys))
    peak = float(ys[i_peak])
    tail = ys[-max(int(0.005 * fs), 1):]
    final = float(np.median(tail))
    after_peak = ys[i_peak:]
    rebound = max(0.0, final - float(after_peak.min())) if after_peak.size else nan
    band = settle_band * stroke
    unsettled = np.nonzero(np.abs(ys - final) > band)[0]
    t_settle = float(t[unsettled[-1]]) if unsettled.size else nan
    if operation == "open" and alpha0 is not None:
        t_damp0 = crossing(alpha0 / stroke)
    else:
        t_damp0 = crossing(1.0 - 0.1)
    return {
        "operating_time_s": t_contact - t_start if np.isfinite(t_contact) else nan,
        "average_speed_rad_s": float(speed),
        "max_travel_rad": float(peak - start),
        "overtravel_rad": float(max(peak - final, 0.0)),
        "rebound_rad": float(rebound),
        "damping_time_s": float(t_settle - t_damp0) if np.isfinite(t_damp0) and t_settle > t_damp0 else nan,
    }
