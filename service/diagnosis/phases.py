"""The physical phases of an operation, from the fitted reduced model's events.

Opening: ``acceleration`` (before α0), ``buffer_engagement`` (the first 5 ms after α0),
``buffer_stroke``, ``approach`` (the last 20 % of the time from α0 to the maximum travel).
Closing: ``free_run`` (camshaft turns, output shaft still), ``cam_rise`` (up to contact touch),
``contact_touch`` (the first half of the remaining time), ``end``.
"""

from __future__ import annotations

import numpy as np

from ..mechanics.effects.contact_wipe import TOUCH_FRACTION

OPEN_PHASES = ("acceleration", "buffer_engagement", "buffer_stroke", "approach")
CLOSE_PHASES = ("free_run", "cam_rise", "contact_touch", "end")


def phase_bounds(operation: str, t_model, theta_model, t_end: float, breaker) -> list:
    """[(name, t0, t1)] in model time [s from the onset of motion] for the fitted curve
    ``theta_model`` [rad] at ``t_model`` [s]; ``t_end`` ends the valid window."""
    if operation == "open":
        t_buf = _first_crossing(t_model, theta_model, breaker.alpha0, t_end)
        t_eng = min(t_buf + 5e-3, t_end)
        t_app = max(t_end - 0.2 * (t_end - t_buf), t_eng)
        edges = [0.0, t_buf, t_eng, t_app, t_end]
        names = OPEN_PHASES
    else:
        h0, h1 = float(breaker.cam.theta2[0]), float(breaker.cam.theta2.max())
        t_rise = _first_crossing(t_model, theta_model, h0 + 1e-3 * (h1 - h0), t_end)
        t_touch = max(_first_crossing(t_model, theta_model, h0 + TOUCH_FRACTION * (h1 - h0), t_end), t_rise)
        t_mid = 0.5 * (t_touch + t_end)
        edges = [0.0, t_rise, t_touch, t_mid, t_end]
        names = CLOSE_PHASES
    return [(n, float(a), float(b)) for n, a, b in zip(names, edges[:-1], edges[1:])]


def _first_crossing(t, y, level, default):
    above = np.nonzero(y >= level)[0]
    if above.size == 0:
        return float(default)
    i = int(above[0])
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (level - y[i - 1]) * (t[i] - t[i - 1]) / (y[i] - y[i - 1]))
