"""The blind trip-strike generator puts its shocks where its truth says, and nothing before."""

import numpy as np
import pytest

from service.prototypes.trip_strike_blind import add_trip

FS = 128_000.0


def _quiet(n=12_800, sd=0.5, seed=0):
    t = np.arange(n) / FS
    return t, np.random.default_rng(seed).normal(0.0, sd, n)


def test_nothing_before_the_strike_and_the_strike_at_its_time():
    t, v0 = _quiet()
    v, truth = add_trip(t, v0, t_motion=0.06, latch_time=8e-3, strike_peak_g=40.0, rng=1)
    before = t < truth.t_strike
    np.testing.assert_array_equal(v[before], v0[before])
    assert truth.t_strike == pytest.approx(0.052)
    assert truth.latch_time == pytest.approx(8e-3)
    # The strike's ring peaks within a millisecond of the strike; the latch's rubbing (2 % of the
    # strike rms by default) rides on it, so the sum is the peak within a few rub sds.
    added = np.abs(v - v0)
    first_ms = (t >= truth.t_strike) & (t < truth.t_strike + 1e-3)
    assert added[first_ms].max() == pytest.approx(40.0, abs=4 * 0.02 * 40.0)
    assert truth.strike_peak_g == pytest.approx(40.0, rel=1e-6)
    # The release rings later, weaker.
    near_release = (t >= truth.t_release) & (t < truth.t_release + 0.3e-3)
    assert added[near_release].max() > 5 * 0.5


def test_the_channel_clips_at_its_full_scale():
    t, v0 = _quiet()
    v, _ = add_trip(t, v0, t_motion=0.06, latch_time=5e-3, strike_peak_g=5000.0, rng=2)
    assert np.abs(v).max() == pytest.approx(1000.0)


def test_a_latch_time_shorter_than_the_release_lead_is_refused_in_words():
    t, v0 = _quiet()
    with pytest.raises(ValueError, match="latch_time .* must exceed release_lead"):
        add_trip(t, v0, t_motion=0.06, latch_time=0.2e-3, strike_peak_g=10.0)
