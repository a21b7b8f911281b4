"""Scripted streams: continuity, truth, laziness, gaps, quantisation."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.stream_script import (Gap, ScriptedOperation, ScriptedStream,
                                               TRAVEL_FULL_SCALE_RAD)


@pytest.fixture(scope="module")
def o_c(breaker):
    ops = [ScriptedOperation("open", 0.1), ScriptedOperation("close", 0.5)]
    return ScriptedStream(breaker, duration_s=0.8, seed=3, operations=ops, noise_rad=0.0,
                          noise_g=0.0, bits=None, gaps=[Gap(0.7, 0.01)])


def test_travel_level_is_continuous_and_rests_where_the_operation_left_it(o_c, breaker):
    travel, _ = o_c.samples(0, o_c.n_samples)
    assert np.max(np.abs(np.diff(travel))) < 0.01  # no jumps at 128 kHz
    assert travel[0] == 0.0                          # starts closed
    assert abs(travel[int(0.45 * o_c.fs)] - breaker.stroke) < 0.05  # rests open
    assert abs(travel[-1]) < 1e-3                    # closed again


def test_truth_marks_shock_motion_and_peak(o_c):
    opening, closing = o_c.truth
    assert opening.operation == "open" and closing.operation == "close"
    assert opening.t_motion_s - opening.t_shock_s == pytest.approx(0.4e-3, abs=1e-5)
    travel, vib = o_c.samples(0, o_c.n_samples)
    k = int(round(opening.t_end_s * o_c.fs))
    window = travel[k - 640:k + 640]
    assert abs(np.argmax(window) - 640) <= 2  # the opening's end is its travel maximum
    shock = opening.shock_index
    assert np.max(np.abs(vib[shock:shock + 64])) > 300 and np.max(np.abs(vib[shock - 64:shock - 1])) < 1e-9


def test_blocks_are_lazy_and_independent_of_block_size(breaker):
    stream = ScriptedStream(breaker, duration_s=1.2, seed=4, gaps=[Gap(0.3, 0.002)])
    a = list(stream.blocks(1000))
    b = list(stream.blocks(70_001))
    cat = lambda blocks: (np.concatenate([x.travel for x in blocks]), [x.first_sample_index for x in blocks])
    (ta, ia), (tb, ib) = cat(a), cat(b)
    assert np.array_equal(ta, tb)
    assert max(x.travel.size for x in a) == 1000
    # The gap shows as a jump in the sample index, never as stitched samples.
    jumps = [(x.first_sample_index - p.end_index) for p, x in zip(a, a[1:]) if x.first_sample_index != p.end_index]
    assert jumps == [int(round(0.002 * stream.fs))]
    assert ta.size == stream.n_samples - jumps[0]
    assert len(stream._cache) <= 2  # memory: at most two generated chunks held


def test_quantised_to_daq_codes(breaker):
    stream = ScriptedStream(breaker, duration_s=0.05, seed=5, operations=[])
    travel, vib = stream.samples(0, stream.n_samples)
    lsb = TRAVEL_FULL_SCALE_RAD / 65535
    assert np.allclose(travel / lsb, np.round(travel / lsb))
    assert np.allclose(vib / (1000 / 32767), np.round(vib / (1000 / 32767)))


def test_default_script_alternates_operations(breaker):
    stream = ScriptedStream(breaker, duration_s=3.0, seed=6)
    assert [t.operation for t in stream.truth] == ["open", "close", "open"]


@pytest.mark.parametrize("ops, message", [
    ([ScriptedOperation("close", 0.1)], "already closed"),
    ([ScriptedOperation("open", 0.3), ScriptedOperation("close", 0.2)], "time order"),
    ([ScriptedOperation("jump", 0.1)], "'open' or 'close'"),
])
def test_impossible_scripts_are_refused(breaker, ops, message):
    with pytest.raises(ValueError, match=message):
        ScriptedStream(breaker, duration_s=1.0, operations=ops)


def clean_opening(breaker, shape):
    """A noise-free opening at 0.1 s with the given return shape: (stream, travel, vibration)."""
    stream = ScriptedStream(breaker, duration_s=0.4, seed=3, operations=[ScriptedOperation("open", 0.1)],
                            noise_rad=0.0, noise_g=0.0, bits=None, return_shape=shape)
    travel, vib = stream.samples(0, stream.n_samples)
    return stream, travel, vib


@pytest.mark.parametrize("shape", ["model", "critical", "oscillating"])
def test_return_shapes_keep_the_arrival_and_the_peak(breaker, shape):
    model, travel_model, _ = clean_opening(breaker, "model")
    stream, travel, _ = clean_opening(breaker, shape)
    k = int(np.floor(stream.truth[0].t_end_s * stream.fs))  # last sample before the peak
    assert stream.truth[0].t_end_s == model.truth[0].t_end_s
    assert np.array_equal(travel[:k + 1], travel_model[:k + 1])  # unchanged up to the peak
    assert np.max(np.abs(np.diff(travel))) < 0.01                  # continuous
    assert abs(np.argmax(travel) - k) <= 1                          # the peak is the maximum
    assert abs(travel[-1] - travel_model[-1]) < 1e-6                # same open rest level


def test_critical_return_is_at_rest_within_5ms_without_passing_it(breaker):
    stream, travel, vib = clean_opening(breaker, "critical")
    fs, k = stream.fs, int(round(stream.truth[0].t_end_s * stream.fs))
    rest, overtravel = travel[-1], travel[k] - travel[-1]
    assert overtravel > 0.01
    after = travel[k + int(0.005 * fs):]
    assert np.max(np.abs(after - rest)) < 0.02 * overtravel  # back at rest 5 ms after the peak
    assert np.min(travel[k:]) >= rest - 1e-9                # critically damped: never past rest
    # The shaft hits its rest stop: a burst 5 ms after the peak.
    j = k + int(0.005 * fs)
    assert np.max(np.abs(vib[j:j + 64])) > 50 and np.max(np.abs(vib[j - 64:j - 1])) < 1.0


def test_oscillating_return_swings_past_rest_and_decays(breaker):
    stream, travel, vib = clean_opening(breaker, "oscillating")
    fs, k = stream.fs, int(round(stream.truth[0].t_end_s * stream.fs))
    rest, overtravel = travel[-1], travel[k] - travel[-1]
    swing = travel[k:k + int(0.05 * fs)]
    assert np.min(swing) < rest - 0.3 * overtravel           # the rebound passes rest
    late = travel[k + int(0.1 * fs):]
    assert np.max(np.abs(late - rest)) < 0.05 * overtravel   # and rings down
    # A burst where the swing first passes rest.
    j = k + int(np.argmax(swing < rest))
    assert np.max(np.abs(vib[j - 2:j + 64])) > 50


def test_unknown_return_shape_is_refused(breaker):
    with pytest.raises(ValueError, match="return shape"):
        ScriptedStream(breaker, duration_s=1.0, return_shape="bouncy")
