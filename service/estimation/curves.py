"""Model curves on the fitting grid, for a whole population of candidates at once.

Each row of ``X`` is one candidate in physical units; the last column is the onset delay τ [s]
between the latch shock (window start) and the start of motion.
"""

from __future__ import annotations

import numpy as np

from ..mechanics.breaker import Breaker
from ..mechanics.closing import closing_angle
from ..mechanics.opening_kernel import opening_curves
from .window import Grid

OPENING_FULL = ("AO", "BO", "DO", "EO", "tau")
OPENING_STAGE1 = ("AO", "BO", "tau")
CLOSING_FULL = ("AC", "BC", "CC", "tau")


class OpeningCurves:
    """Eq. 11 on a grid of block centres, with the block-average curvature correction."""

    def __init__(self, breaker: Breaker, grid: Grid):
        self.CO = breaker.CO
        self.alpha0 = breaker.alpha0
        self.grid = grid

    def pre_buffer(self, X):
        """Stage 1: the segment before α0 only; X columns AO, BO, τ. Returns (n, m) [rad]."""
        return opening_curves(np.ascontiguousarray(X, dtype=float), self.grid.t, self.grid.spread,
                              self.CO, self.alpha0, False)

    def full(self, X):
        """The whole valid interval; X columns AO, BO, DO, EO, τ. Returns (n, m) [rad]."""
        return opening_curves(np.ascontiguousarray(X, dtype=float), self.grid.t, self.grid.spread,
                              self.CO, self.alpha0, True)

    @staticmethod
    def at(t, x, breaker: Breaker):
        """Opening angle [rad] at capture-window times ``t`` [s] for one parameter vector."""
        t = np.ascontiguousarray(t, dtype=float)
        X = np.ascontiguousarray(np.atleast_2d(np.asarray(x, dtype=float)))
        return opening_curves(X, t, np.zeros_like(t), breaker.CO, breaker.alpha0, True)[0]


class ClosingCurves:
    """Eq. 7 on the grid (compiled RK4 with one step per grid interval); X columns AC, BC, CC, τ."""

    def __init__(self, breaker: Breaker, grid: Grid, dc: float, dt_max: float = 1 / 16000):
        self.cam = breaker.cam
        self.geometry = breaker.closing_geometry
        self.grid = grid
        self.dc = float(dc)
        spacing = float(np.median(np.diff(grid.t))) if grid.t.size > 1 else 1e-4
        self.dt_max = min(spacing, dt_max)

    def full(self, X):
        X = np.atleast_2d(X)
        P = np.column_stack([X[:, 0], X[:, 1], X[:, 2], np.full(X.shape[0], self.dc)])
        theta2, _, _, _ = closing_angle(self.grid.t, P, cam=self.cam, geometry=self.geometry,
                                        dt_max=self.dt_max, tau=X[:, 3])
        return theta2

    @staticmethod
    def at(t, x, breaker: Breaker, dc: float):
        """θ2 [rad] at capture-window times ``t`` [s] (non-decreasing) for one parameter vector."""
        AC, BC, CC, tau = x
        theta2, _, _, _ = closing_angle(np.asarray(t, dtype=float), np.array([[AC, BC, CC, dc]]),
                                        cam=breaker.cam, geometry=breaker.closing_geometry,
                                        dt_max=1 / 64000, tau=np.array([tau]))
        return theta2[0]


def weighted_rmse(model, grid: Grid, within_ss: float = 0.0):
    """RMSE [rad] at the measured samples, from block means.

    Σ(y − m)² over the samples splits into Σ count·(ȳ − m̄)² over the blocks plus the
    within-block scatter ``within_ss`` [rad²] (noise, independent of the candidate), so this is the
    paper's RMSE against the measured curve without touching every sample.
    """
    r = model - grid.y[None, :]
    return np.sqrt((np.sum(grid.count * r * r, axis=1) + within_ss) / np.sum(grid.count))
