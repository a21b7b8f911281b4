"""From openings to dates: the breaker's own duty cycle as a renewal process.

Pure, numpy only. The times between fitted openings over the last year are the sample of the
duty cycle. Its rate is one over their mean gap, the renewal-rate estimate: the gap that
straddles the year's start counts whole, so the rate does not depend on where the window happens
to start (counting the openings inside the window and dividing by the span from the first of
them would leave out the idle time before it).

A date interval carries both the spread of the openings still to come (the crossing's own
distribution in operations) and the spread of the time they take: the time to the N-th opening
from now is the sum of N future gaps, drawn by a circular block bootstrap of the last year's gaps
(Politis & Romano 1992; blocks of about sqrt(G) gaps keep the bursts of an irregular duty cycle
together: storms of operations, then weeks idle). Seeded: the same history gives the same dates.
"""

from __future__ import annotations

import math

import numpy as np

DAYS_PER_YEAR = 365.25
DRAWS = 2000
SEED = 1992
# Above this many blocks a sum of block sums is normal to well within the draws' own error.
EXACT_BLOCKS = 200


def recent_gaps(times_days: np.ndarray) -> np.ndarray:
    """Gaps between consecutive openings [days] whose later opening lies within the last year,
    including the one that straddles the year's start."""
    t = np.asarray(times_days, dtype=float)
    if t.size < 2:
        return np.zeros(0)
    gaps = np.diff(t)
    return gaps[t[1:] >= t[-1] - DAYS_PER_YEAR]


def operation_rate(times_days: np.ndarray) -> float | None:
    """Openings per day [1/day]: one over the mean gap of the last year; None when the gaps span
    less than a day."""
    g = recent_gaps(times_days)
    if g.size == 0 or g.sum() < 1.0:
        return None
    return float(g.size / g.sum())


def days_to_operations(ops: np.ndarray, gaps: np.ndarray, *, seed: int = SEED) -> np.ndarray:
    """Time [days] until each of ``ops`` (whole operations from now, >= 0; inf: never) further
    openings, each the sum of that many gaps drawn by a circular block bootstrap of ``gaps``."""
    ops = np.asarray(ops, dtype=float)
    out = np.full(ops.shape, math.inf)
    g = np.asarray(gaps, dtype=float)
    size = g.size
    if size == 0:
        return out
    b = max(1, round(math.sqrt(size)))
    cs = np.concatenate([[0.0], np.cumsum(np.concatenate([g, g[:b]]))])
    block = cs[b:b + size] - cs[:size]  # the sum of the b gaps starting at each gap
    rng = np.random.default_rng(seed)
    fin = np.isfinite(ops)
    n = np.where(fin, ops, 0.0).astype(np.int64)
    k, rem = n // b, n % b
    total = np.zeros(ops.shape)
    exact = fin & (k <= EXACT_BLOCKS)
    kmax = int(k[exact].max()) if exact.any() else 0
    if kmax:
        starts = rng.integers(size, size=(ops.size, kmax))
        used = np.arange(kmax)[None, :] < k[:, None]
        total += np.where(exact[:, None] & used, block[starts], 0.0).sum(axis=1)
    big = fin & ~exact
    if big.any():  # the sum of many block sums: its normal approximation
        total[big] = k[big] * block.mean() + np.sqrt(k[big]) * block.std() * rng.standard_normal(int(big.sum()))
    s = rng.integers(size, size=ops.size)
    total += cs[s + rem] - cs[s]
    out[fin] = total[fin]
    return out


def sample_operations(cdf: np.ndarray, ahead: np.ndarray, draws: int = DRAWS, *, seed: int = SEED) -> np.ndarray:
    """Draws of the whole operations to the crossing from its cdf ``cdf`` on ``ahead`` (operations
    from now, increasing; cdf at 0 is the probability it has crossed already); inf past the grid."""
    u = np.random.default_rng(seed).random(draws)
    f = np.maximum.accumulate(np.asarray(cdf, dtype=float))
    j = np.searchsorted(f, u, side="left")
    out = np.full(draws, math.inf)
    ok = j < len(ahead)
    out[ok] = np.ceil(np.asarray(ahead, dtype=float)[j[ok]] - 1e-9)
    return out


def date_quantiles(cdf: np.ndarray, ahead: np.ndarray, gaps: np.ndarray, ps) -> list[float]:
    """Quantiles ``ps`` of the time to the crossing [days from now]: the crossing's operations
    drawn from ``cdf`` on ``ahead``, each turned into days by the gaps' bootstrap; inf where the
    draws do not cross."""
    ops = sample_operations(cdf, ahead)
    days = days_to_operations(ops, gaps)
    return [float(np.quantile(days, p, method="inverted_cdf")) for p in ps]
