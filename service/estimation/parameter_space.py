"""Physical parameter ranges and their map to the unit cube CMA-ES searches (paper Section 3.3)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EDGE = 0.01  # an estimate this close to a range edge (normalised) triggers re-adaptation


@dataclass(frozen=True)
class ParameterSpace:
    """Names and [lo, hi] ranges of the parameters one CMA-ES stage searches.

    Attributes
    ----------
    names : tuple of str
    lo, hi : ndarray
        Range limits in physical units (s^-2, s^-1, -, s).
    """

    names: tuple
    lo: np.ndarray
    hi: np.ndarray

    @classmethod
    def from_ranges(cls, names, ranges: dict) -> "ParameterSpace":
        lo = np.array([float(ranges[n][0]) for n in names])
        hi = np.array([float(ranges[n][1]) for n in names])
        if np.any(hi <= lo):
            raise ValueError(f"empty parameter range in {dict(zip(names, zip(lo, hi)))}")
        return cls(tuple(names), lo, hi)

    def to_physical(self, u):
        """Unit-cube coordinates -> physical values (broadcasts over leading axes)."""
        return self.lo + np.asarray(u, dtype=float) * (self.hi - self.lo)

    def to_unit(self, x):
        return (np.asarray(x, dtype=float) - self.lo) / (self.hi - self.lo)

    def edges_hit(self, x, fixed: tuple = ()) -> list:
        """Names of the parameters whose estimate ``x`` sits on a range edge."""
        u = self.to_unit(x)
        return [n for n, ui in zip(self.names, u) if n not in fixed and (ui < EDGE or ui > 1 - EDGE)]

    def readapted(self, x, fixed: tuple = ()) -> "ParameterSpace":
        """Steps 5–6 of the paper: shift an edge-bound range so the estimate is interior.

        The range keeps its width and is re-centred on the estimate; a parameter that must stay
        positive keeps a strictly positive lower bound.
        """
        x = np.asarray(x, dtype=float)
        u = self.to_unit(x)
        lo, hi = self.lo.copy(), self.hi.copy()
        for i, name in enumerate(self.names):
            if name in fixed or EDGE <= u[i] <= 1 - EDGE:
                continue
            width = hi[i] - lo[i]
            lo[i] = max(x[i] - 0.5 * width, 1e-3 * width if self.lo[i] > 0 else -np.inf)
            hi[i] = lo[i] + width
        return ParameterSpace(self.names, lo, hi)

    def as_dict(self) -> dict:
        return {n: [float(a), float(b)] for n, a, b in zip(self.names, self.lo, self.hi)}
