"""One backoff for every retry loop: exponential ceiling, equal jitter, reset on success."""

import random

import pytest

from drivers.backoff import Backoff


def test_delays_lie_in_the_upper_half_of_a_doubling_ceiling_capped_at_the_maximum():
    b = Backoff(0.5, 8.0, rng=random.Random(1))
    ceilings = [0.5, 1, 2, 4, 8, 8, 8]
    for c in ceilings:
        d = b.next()
        assert c / 2 <= d <= c
    b.reset()
    assert b.next() <= 0.5


def test_a_fleet_retrying_after_the_same_outage_spreads_out():
    """Twenty agents that failed at the same instant do not retry at the same instant."""
    delays = []
    for seed in range(20):
        b = Backoff(1.0, 60.0, rng=random.Random(seed))
        delays.append(sum(b.next() for _ in range(4)))  # the 4th retry's start
    assert max(delays) - min(delays) > 1.0  # ceilings 1+2+4+8: spread of several seconds
    assert len({round(d, 3) for d in delays}) == 20


@pytest.mark.parametrize("lo,hi", [(0, 1), (-1, 1), (2, 1)])
def test_nonsense_bounds_are_refused_in_words(lo, hi):
    with pytest.raises(ValueError, match="minimum"):
        Backoff(lo, hi)
