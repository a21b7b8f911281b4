"""Min/max decimation: draw a long series with a few points per bucket and lose no excursion.

The web page's charts (trends, vibration) and the preview a pruned capture leaves behind use
these two functions; a one-sample shock survives any decimation because each bucket keeps its
minimum and its maximum.
"""

from __future__ import annotations

import numpy as np


def bucket_edges(n: int, buckets: int) -> np.ndarray:
    """``buckets`` + 1 sample indices cutting ``n`` samples into near-equal slices."""
    return np.linspace(0, n, buckets + 1).astype(int)


def minmax_indices(y, buckets: int) -> np.ndarray:
    """Sorted indices of each bucket's minimum and maximum, plus the first and last sample.

    NaN and None are skipped (a bucket of only NaN gives nothing). At most 2·buckets + 2
    indices; all of them when ``y`` has no more than 2·buckets samples.
    """
    y = np.asarray([np.nan if v is None else v for v in y] if isinstance(y, list) else y, dtype=float)
    n = y.size
    if n <= 2 * buckets:
        return np.arange(n)
    edges = bucket_edges(n, buckets)
    keep = [0, n - 1]
    for a, b in zip(edges[:-1], edges[1:]):
        seg = y[a:b]
        if seg.size == 0 or np.all(np.isnan(seg)):
            continue
        keep += [a + int(np.nanargmin(seg)), a + int(np.nanargmax(seg))]
    return np.unique(np.asarray(keep, dtype=int))


def minmax_buckets(t, y, buckets: int) -> tuple[list, list, list]:
    """``buckets`` equal slices of the samples, each as (start time, minimum, maximum).

    t [s], y [any unit]; returns three lists. With fewer samples than buckets every sample is
    its own bucket (min = max).
    """
    t, y = np.asarray(t, float), np.asarray(y, float)
    n = y.size
    if n == 0:
        return [], [], []
    edges = bucket_edges(n, max(1, min(int(buckets), n)))
    lo = np.minimum.reduceat(y, edges[:-1])
    hi = np.maximum.reduceat(y, edges[:-1])
    return t[edges[:-1]].tolist(), lo.tolist(), hi.tolist()


def shared_minmax_indices(series, points: int) -> np.ndarray:
    """Sorted sample indices that keep every bucket's minimum and maximum of each of several
    sample-aligned series (travel, coil currents, DCRM), so they share one time axis.

    ``(points − 2) // (2·len(series))`` buckets per series (at least one): each gives at most two
    indices a bucket plus the first and last sample, which all share, so at most ``points``
    indices come back (``2·len(series) + 2`` when ``points`` is smaller); all of them when the
    series are no longer than ``points``.
    """
    series = [np.asarray(y, dtype=float) for y in series]
    if not series:
        return np.arange(0)
    n = series[0].size
    buckets = max(1, (points - 2) // (2 * len(series)))
    if n <= points:
        return np.arange(n)
    return np.unique(np.concatenate([minmax_indices(y, buckets) for y in series]))
