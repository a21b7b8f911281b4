"""Interface checks of the blind degradation histories (bench/prognosis_shapes_blind.py)."""
import numpy as np
import pytest

from bench.prognosis_shapes_blind import (
    NEVER_CROSSES,
    SHAPES,
    BlindHistory,
    truth_crossing,
)

SEEDS = range(4)


def _all():
    for name, make in SHAPES.items():
        for seed in SEEDS:
            yield name, seed, make(np.random.default_rng(seed))


HISTORIES = list(_all())


def test_enough_shapes():
    degrading = {n for n, _, h in HISTORIES if h.degrading}
    healthy = {n for n, _, h in HISTORIES if not h.degrading}
    assert len(degrading) >= 6 and len(healthy) >= 2
    assert not degrading & healthy, "a shape must be degrading or healthy for every seed"


@pytest.mark.parametrize("name,seed,h", HISTORIES, ids=[f"{n}-{s}" for n, s, _ in HISTORIES])
def test_history_is_well_formed(name, seed, h: BlindHistory):
    n = h.times_s.size
    assert h.shape == name and h.parameter in ("DO", "BO") and h.notes
    assert 200 <= n <= 1500
    arrays = [h.true_level, h.temperature_effect, h.observed, h.fit_ci95_halfwidth]
    if h.temperature_c is not None:
        arrays.append(h.temperature_c)
    else:
        assert np.all(h.temperature_effect == 0.0)
    for a in [h.times_s, *arrays]:
        assert a.shape == (n,) and np.all(np.isfinite(a))
    assert h.times_s[0] == 0.0 and np.all(np.diff(h.times_s) > 0)
    assert np.all(h.fit_ci95_halfwidth > 0)
    assert 0.006 < np.median(h.fit_ci95_halfwidth / np.abs(h.observed)) < 0.015
    lo, hi = (30, 45) if h.parameter == "DO" else (3000, 5000)
    assert lo <= h.baseline <= hi and h.limit_change < 0
    assert np.isfinite(h.reference_temperature_c)
    # the noise sits around the true level plus the temperature effect (outliers aside; the first
    # 100 operations, before any sensor offset)
    rel = ((h.observed - h.true_level - h.temperature_effect) / h.true_level)[:100]
    assert abs(np.median(rel)) < 0.02 and np.median(np.abs(rel)) < 0.05


@pytest.mark.parametrize("name,seed,h", HISTORIES, ids=[f"{n}-{s}" for n, s, _ in HISTORIES])
def test_truth_crossing_matches_true_level(name, seed, h: BlindHistory):
    limit = h.baseline * (1 + h.limit_change)
    c = truth_crossing(h)
    if c is None:
        assert np.all(h.true_level > limit)
    else:
        assert h.true_level[c] <= limit and np.all(h.true_level[:c] > limit)
    if h.degrading:
        assert np.all(h.true_level[:100] == h.baseline), "onset after >= 100 healthy operations"
        assert (c is None) == (name in NEVER_CROSSES)
        if c is not None:
            assert c <= h.times_s.size - 15
    else:
        assert isinstance(h.true_crosses_within_10y, bool)
        if c is not None:   # crossing inside the window implies crossing within 10 years
            assert h.true_crosses_within_10y


def test_same_seed_same_history():
    for make in SHAPES.values():
        a, b = make(np.random.default_rng(7)), make(np.random.default_rng(7))
        assert np.array_equal(a.observed, b.observed) and np.array_equal(a.times_s, b.times_s)
