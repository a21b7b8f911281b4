"""The average of the candidate paths: a mixture of their crossing distributions and levels.

Pure, numpy/scipy only. Curves (paths.py) have a Student t level, so the probability that the
level has crossed a limit by operation n is the t cdf (Gebraeel et al. 2005, eq. 12); stochastic
paths (wiener.py) give their own first-passage probability. The mixture's crossing cdf is the
weighted sum; its quantiles are whole operations.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special


def ahead_grid(horizon: float) -> np.ndarray:
    """Operations ahead at which the crossing's distribution is evaluated: every one of the
    first 100, then 120 points spaced geometrically to twice the horizon (the quantiles between
    two points are refined over whole operations)."""
    return np.unique(np.concatenate([np.arange(1.0, 100.0), np.geomspace(100.0, 2.0 * horizon + 200.0, 120)]))


class Mixture:
    """The stacked average of candidate paths: a mixture of Student t levels."""

    def __init__(self, candidates, weights):
        # Candidates below a thousandth of the weight move no quantile the answer shows.
        self.c = [c for c, w in zip(candidates, weights) if w > 1e-3]
        self.w = np.array([w for w in weights if w > 1e-3])
        self.w = self.w / self.w.sum()
        self._cdf = {}

    def probability_falling(self) -> float:
        """P(the drift coefficient b < 0) under the average [-]: with 0.05-0.95 its 90 % interval
        holds zero, "no trend"."""
        return float(sum(w * special.stdtr(c.dof, -c.beta[1] / math.sqrt(max(c.cov[1, 1], 1e-300)))
                         for c, w in zip(self.c, self.w)))

    def crossing_probability(self, limit: float, direction: str, n: np.ndarray) -> np.ndarray:
        """P(the level has crossed ``limit`` by operation ``n``) [-] (Gebraeel et al. 2005, eq. 12,
        averaged over the candidates with their weights)."""
        sign = 1.0 if direction == "falling" else -1.0
        out = np.zeros(len(n))
        for c, w in zip(self.c, self.w):
            if hasattr(c, "crossing_probability"):  # a stochastic path: its first passage
                out += w * c.crossing_probability(limit, direction, n)
                continue
            mean, scale = c.level(n)
            z = sign * (limit - mean) / np.maximum(scale, 1e-300)
            out += w * special.stdtr(c.dof, z)
        return out

    def crossing_cdf(self, limit: float, direction: str, *, n_now: float, horizon: float):
        """(operations ahead [0, then ahead_grid(horizon)], P(crossed by then)), computed once per
        question and kept: the quantiles and the dates all read it."""
        key = (limit, direction, n_now, horizon)
        if key not in self._cdf:
            ahead = np.concatenate([[0.0], ahead_grid(horizon)])
            self._cdf[key] = (ahead, np.maximum.accumulate(self.crossing_probability(limit, direction, n_now + ahead)))
        return self._cdf[key]

    def crossing_quantile(self, limit: float, direction: str, p: float, *, n_now: float,
                          horizon: float) -> float:
        """Whole operations from now by which the level has crossed ``limit`` with probability
        ``p`` (the first opening with P >= p); 0 when it has already, ``inf`` when not within 2x
        the horizon."""
        ahead, f = self.crossing_cdf(limit, direction, n_now=n_now, horizon=horizon)
        hit = np.flatnonzero(f >= p)
        if not hit.size:
            return math.inf
        j = hit[0]
        if j == 0:
            return 0.0
        lo, hi = math.floor(ahead[j - 1]), math.ceil(ahead[j])
        while hi - lo > 1:  # bisection over whole operations between two grid points
            mid = (lo + hi) // 2
            if self.crossing_probability(limit, direction, np.array([n_now + mid]))[0] >= p:
                hi = mid
            else:
                lo = mid
        return float(hi)

    def level_quantiles(self, n: np.ndarray, ps) -> list[np.ndarray]:
        """The level's p-quantiles after operations ``n`` [unit], by bisection on the mixture cdf."""
        ms = [c.level(n) for c in self.c]
        mean = np.array([m for m, _ in ms])  # [K, G]
        scale = np.maximum(np.array([s for _, s in ms]), 1e-300)
        dof, w = np.array([c.dof for c in self.c])[:, None], self.w[:, None]
        # Student t with >= 3 dof: a 5-95 % quantile lies within 12 scales of some component's mean.
        lo, hi = (mean - 12 * scale).min(axis=0) - 1e-9, (mean + 12 * scale).max(axis=0) + 1e-9
        out = []
        for p in ps:
            a, b = lo.copy(), hi.copy()
            for _ in range(30):  # 24 scales / 2^30: far below a fit's resolution
                mid = 0.5 * (a + b)
                below = (w * special.stdtr(dof, (mid - mean) / scale)).sum(axis=0) < p
                a, b = np.where(below, mid, a), np.where(below, b, mid)
            out.append(0.5 * (a + b))
        return out
