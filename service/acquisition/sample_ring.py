"""Fixed-capacity ring of the latest stream samples (travel, vibration, valid), indexed by
stream sample index, so the trigger's memory does not depend on how long the stream runs."""

from __future__ import annotations

import numpy as np


class SampleRing:
    """Fixed-capacity ring of the latest samples; ``valid`` is False for samples lost in a gap."""

    def __init__(self, capacity: int):
        self.capacity = int(capacity)
        self.travel = np.zeros(self.capacity)
        self.vibration = np.zeros(self.capacity, dtype=np.float32)
        self.valid = np.zeros(self.capacity, dtype=bool)
        self.end = 0    # stream index one past the newest sample
        self.first = 0  # oldest stream index ever stored

    def reset(self, index: int):
        self.end = self.first = int(index)
        self.valid[:] = False

    @property
    def start(self) -> int:
        """Oldest stream index still held."""
        return max(self.first, self.end - self.capacity)

    def append(self, travel, vibration, valid: bool = True):
        n = len(travel)
        if n > self.capacity:  # only the newest samples fit
            self.end += n - self.capacity
            travel, vibration, n = travel[-self.capacity:], vibration[-self.capacity:], self.capacity
        pos = self.end % self.capacity
        head = min(n, self.capacity - pos)
        for dst, src in ((self.travel, travel), (self.vibration, vibration)):
            dst[pos:pos + head] = src[:head]
            dst[:n - head] = src[head:]
        self.valid[pos:pos + head] = valid
        self.valid[:n - head] = valid
        self.end += n

    def fill_gap(self, n: int):
        """Account for ``n`` lost samples: held travel, zero vibration, marked invalid."""
        last = self.travel[(self.end - 1) % self.capacity] if self.end > self.first else 0.0
        m = min(n, self.capacity)
        self.end += n - m
        self.append(np.full(m, last), np.zeros(m, dtype=np.float32), valid=False)

    def _pieces(self, i0: int, i1: int):
        """Ring slices covering stream indices [i0, i1) ∩ held samples, oldest first."""
        i0, i1 = max(i0, self.start), min(i1, self.end)
        if i1 <= i0:
            return i0, []
        p0 = i0 % self.capacity
        n = i1 - i0
        if p0 + n <= self.capacity:
            return i0, [slice(p0, p0 + n)]
        return i0, [slice(p0, self.capacity), slice(0, n - (self.capacity - p0))]

    def get(self, i0: int, i1: int):
        """Copies of travel, vibration and valid for stream indices [i0, i1) ∩ held samples."""
        i0, pieces = self._pieces(i0, i1)
        if not pieces:
            return i0, np.empty(0), np.empty(0), np.empty(0, dtype=bool)
        return (i0, np.concatenate([self.travel[p] for p in pieces]),
                np.concatenate([self.vibration[p] for p in pieces]).astype(float),
                np.concatenate([self.valid[p] for p in pieces]))

    def first_exceedance(self, i0: int, threshold: float) -> int | None:
        """Stream index of the first valid sample at or after ``i0`` with |vibration| ≥ threshold."""
        i0, pieces = self._pieces(i0, self.end)
        for p in pieces:
            hits = np.flatnonzero((np.abs(self.vibration[p]) >= threshold) & self.valid[p])
            if hits.size:
                return i0 + int(hits[0])
            i0 += p.stop - p.start
        return None
