"""Angle sensor whose gain departs smoothly from linear (``sensor_nonlinearity``).

A resistive angle sensor's characteristic bows between its calibration points, the closed and
the open position (u = travel/stroke):

    travel_measured = travel + ε_s·stroke·4·u·(1 − u)

It changes nothing in the dynamics, only what the travel channel reads. ε_s = 0 is a linear
sensor.
"""

from __future__ import annotations

import numpy as np


def sensor_reading(travel, eps, stroke):
    """Measured travel [rad from closed] for true travel [rad]."""
    travel = np.asarray(travel, dtype=float)
    if eps == 0.0:
        return travel
    u = travel / stroke
    return travel + eps * stroke * 4.0 * u * (1.0 - u)
