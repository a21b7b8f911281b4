"""The one place where the measured travel becomes an operation's own coordinate.

The travel channel is the output-shaft angle from the closed position [rad]: it rises while
opening and falls while closing. The opening model's θ is the travel itself; the closing
model's θ2 (0 = open) is ``stroke - travel``, with ``stroke`` the open rest angle [rad].
"""

from __future__ import annotations

import numpy as np

OPERATIONS = ("open", "close")


def operation_coordinate(travel, operation: str, stroke: float):
    """Travel [rad from closed] -> the operation's own coordinate [rad]."""
    travel = np.asarray(travel, dtype=float)
    if operation == "open":
        return travel
    if operation == "close":
        return stroke - travel
    raise ValueError(f"operation must be 'open' or 'close', got {operation!r}")


def travel_from_coordinate(theta, operation: str, stroke: float):
    """Inverse of :func:`operation_coordinate`."""
    theta = np.asarray(theta, dtype=float)
    if operation == "open":
        return theta
    if operation == "close":
        return stroke - theta
    raise ValueError(f"operation must be 'open' or 'close', got {operation!r}")
