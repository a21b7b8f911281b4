"""Angle sensor whose gain departs smoothly from linear (``sensor_nonlinearity``).

A resistive angle sensor's characteristic bows between its calibration points, the closed and
the open position (u = travel/stroke):

    travel_measured = travel + ε_s·stroke·4·u·(1 − u)

It changes nothing in the dynamics, only what the travel channel reads. ε_s = 0 is a linear
sensor.
"""

from __future__ import annotations

import numpy as np


def sensor_reading(travel, eps, stroke, power=2.0, end_calibration=1.0):
    """Measured travel [rad from closed] for true travel [rad].

    Family (diagnosis): the error is a polynomial zero at the closed position,
    e = −ε·stroke·(u^p − g·u)/max|u^p − g·u| over the stroke, p = ``power`` 2 … 3, g =
    ``end_calibration`` (1: also zero at the open position, 0: a sensor zeroed only at closed).
    The prototype's own bow is p = 2, g = 1: e = ε·stroke·4u(1 − u). ε < 0 reads high."""
    travel = np.asarray(travel, dtype=float)
    if eps == 0.0:
        return travel
    u = travel / stroke
    grid = np.linspace(0.0, 1.0, 201)
    norm = float(np.max(np.abs(grid ** power - end_calibration * grid))) or 1.0
    return travel - eps * stroke * (np.abs(u) ** power * np.sign(u) - end_calibration * u) / norm
