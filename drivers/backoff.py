"""Retry delays that grow exponentially and carry jitter.

Without jitter, every agent and DAQ link that lost the same server retries at the same instants
after an outage and meets it again in step. "Equal jitter" (M. Brooker, "Exponential Backoff And
Jitter", AWS Architecture Blog, 2015) draws each delay uniformly in the upper half of the
exponential ceiling: the mean still doubles per failure, no delay is below half the ceiling, and
retries of a fleet spread over that half.
"""

from __future__ import annotations

import random


class Backoff:
    """Delays for successive failures: ``next()`` after each one, ``reset()`` after a success.

    Parameters
    ----------
    minimum_s : float
        Ceiling of the first delay [s]; the delays lie in [ceiling/2, ceiling].
    maximum_s : float
        Largest ceiling [s].
    rng : random.Random, optional
        Source of the jitter (tests pass a seeded one).
    """

    def __init__(self, minimum_s: float, maximum_s: float, *, rng: random.Random | None = None):
        if not (minimum_s > 0 and maximum_s >= minimum_s):
            raise ValueError(f"backoff needs 0 < minimum ≤ maximum, got {minimum_s} and {maximum_s} s")
        self.minimum_s, self.maximum_s = float(minimum_s), float(maximum_s)
        self._rng = rng or random.Random()
        self.failures = 0

    @property
    def ceiling_s(self) -> float:
        """Ceiling of the next delay [s]."""
        return min(self.maximum_s, self.minimum_s * 2.0 ** min(self.failures, 64))

    def next(self) -> float:
        """The delay to wait after one more failure [s]."""
        ceiling = self.ceiling_s
        self.failures += 1
        return self._rng.uniform(ceiling / 2.0, ceiling)

    def reset(self) -> None:
        self.failures = 0
