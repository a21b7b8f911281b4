"""The cam kinematics θ2 = h(θ1) of prototype D as a dense table the integrator reads.

The reference profile (``config/breakers/reference-252kV.cam.csv``: camshaft angle θ1 [rad] →
output-shaft angle θ2 [rad], closing coordinate) is fitted with a quintic interpolating spline,
so h, h′ and h″ are continuous, and tabulated on a uniform grid fine enough (10⁻⁴ rad) that the
integrator's Hermite look-up adds an error far below the sensor noise.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.interpolate import make_interp_spline

PROFILE = Path(__file__).resolve().parents[3] / "config" / "breakers" / "reference-252kV.cam.csv"
STEP_RAD = 1e-4


@lru_cache(maxsize=1)
def cam_spline():
    """The quintic spline h(θ1) [rad → rad] through the reference profile."""
    data = np.loadtxt(PROFILE, delimiter=",", skiprows=1)
    return make_interp_spline(data[:, 0], data[:, 1], k=5)


@lru_cache(maxsize=1)
def cam_table() -> np.ndarray:
    """Rows (θ1 [rad], h [rad], h′ [-], h″ [rad⁻¹]) on a uniform 10⁻⁴ rad grid over the profile."""
    spline = cam_spline()
    lo, hi = float(spline.t[0]), float(spline.t[-1])
    grid = np.arange(lo, hi + STEP_RAD / 2, STEP_RAD)
    return np.column_stack([grid, spline(grid), spline(grid, 1), spline(grid, 2)])
