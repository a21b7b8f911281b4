"""The result object every simulator returns."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class SimulationError(RuntimeError):
    """A simulation could not produce a valid trajectory."""


@dataclass(frozen=True)
class Trajectory:
    """A simulated operation.

    Attributes
    ----------
    t : ndarray
        Time since the start of motion [s].
    theta : ndarray
        The operation's own coordinate [rad]: the opening angle from the closed position for an
        opening, the closing-coordinate output-shaft angle θ2 (0 = open) for a closing.
    omega : ndarray
        Its time derivative [rad/s].
    success : bool
        False when the motion did not complete (for example a closing that stalls).
    message : str
        Why, in words an engineer understands.
    t_peak : float
        Time of the maximum of ``theta``: the end of the valid interval [s]; NaN if not reached.
    events : dict
        Named instants [s], e.g. ``buffer_engaged`` or ``cam_rise``.
    """

    t: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    success: bool
    message: str
    t_peak: float
    events: dict = field(default_factory=dict)

    def raise_for_status(self) -> "Trajectory":
        if not self.success:
            raise SimulationError(self.message)
        return self
