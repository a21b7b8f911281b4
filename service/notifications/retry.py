"""When a failed route tries again: exponential backoff (pure)."""

from __future__ import annotations


def backoff_s(failures: int, *, first_s: float, max_s: float) -> float:
    """Wait after the ``failures``-th consecutive failure [s]: first_s, 2 first_s, 4 first_s, ...
    up to max_s. Doubling keeps an unreachable receiver's load at log2(max/first) + elapsed/max
    attempts, while a receiver back after a short outage is found within about the outage's length."""
    if failures <= 0:
        return 0.0
    return min(max_s, first_s * 2.0 ** min(failures - 1, 60))
