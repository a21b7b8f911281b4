"""Cam kinematics θ2 = h(θ1) (Eq. 4) from the offline-measured cam table.

A C² cubic spline gives continuous h' and h'' (Eq. 7 needs both). Outside the table the cam
dwells: h is held at its end value with h' = h'' = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline


class CamProfileError(ValueError):
    """The cam table cannot describe a cam."""


@dataclass(frozen=True)
class CamProfile:
    """Interpolated cam table.

    Attributes
    ----------
    theta1 : ndarray
        Camshaft angle knots [rad], strictly increasing.
    theta2 : ndarray
        Output-shaft angle in the closing coordinate at the knots [rad] (0 = open).
    coefficients : ndarray, shape (4, n-1)
        Cubic coefficients per interval, highest power first (scipy ``PPoly`` layout).
    """

    theta1: np.ndarray
    theta2: np.ndarray
    coefficients: np.ndarray

    @classmethod
    def from_table(cls, theta1, theta2) -> "CamProfile":
        """Build the interpolant, refusing tables that are not a cam.

        Parameters
        ----------
        theta1 : array_like
            Camshaft angle [rad], strictly increasing.
        theta2 : array_like
            Output-shaft angle, closing coordinate [rad], non-decreasing (a closing cam never
            drives the output shaft backwards).
        """
        x = np.asarray(theta1, dtype=float)
        y = np.asarray(theta2, dtype=float)
        if x.ndim != 1 or x.shape != y.shape or x.size < 4:
            raise CamProfileError("the cam table needs at least 4 rows of (camshaft, output shaft) angles")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise CamProfileError("the cam table contains NaN or infinite angles")
        if np.any(np.diff(x) <= 0):
            raise CamProfileError("the cam table's camshaft angles are not strictly increasing")
        if np.any(np.diff(y) < -1e-9):
            i = int(np.argmax(np.diff(y) < -1e-9))
            raise CamProfileError(
                f"the cam table is not monotone: the output shaft goes back from {y[i]:.6f} "
                f"to {y[i + 1]:.6f} rad at camshaft angle {x[i + 1]:.6f} rad")
        if np.ptp(y) <= 0:
            raise CamProfileError("the cam table never moves the output shaft")
        spline = CubicSpline(x, y, bc_type="natural")
        return cls(x, y, np.ascontiguousarray(spline.c))

    @property
    def stroke(self) -> float:
        """Total output-shaft rise [rad]."""
        return float(self.theta2[-1] - self.theta2[0])

    @property
    def rise_start(self) -> float:
        """Camshaft angle where the output shaft starts to move [rad]."""
        moving = np.nonzero(self.theta2 > self.theta2[0] + 1e-9)[0]
        return float(self.theta1[max(moving[0] - 1, 0)])

    @property
    def rise_end(self) -> float:
        """Camshaft angle where the output shaft first reaches its maximum [rad]."""
        return float(self.theta1[int(np.argmax(self.theta2 >= self.theta2.max() - 1e-9))])

    def evaluate(self, theta1):
        """h, h' and h'' at camshaft angles ``theta1`` [rad] -> ([rad], [-], [rad^-1])."""
        x = np.asarray(theta1, dtype=float)
        k = np.clip(np.searchsorted(self.theta1, x, side="right") - 1, 0, self.theta1.size - 2)
        s = x - self.theta1[k]
        c = self.coefficients[:, k]
        h = ((c[0] * s + c[1]) * s + c[2]) * s + c[3]
        h1 = (3 * c[0] * s + 2 * c[1]) * s + c[2]
        h2 = 6 * c[0] * s + 2 * c[1]
        below = x < self.theta1[0]
        above = x > self.theta1[-1]
        h = np.where(below, self.theta2[0], np.where(above, self.theta2[-1], h))
        h1 = np.where(below | above, 0.0, h1)
        h2 = np.where(below | above, 0.0, h2)
        return h, h1, h2
