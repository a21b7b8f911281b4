"""Trigger robustness: lone shocks, noise bursts, clipping, gaps, restarts, bounded memory."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.interface import SampleBlock
from drivers.stream_script import Gap, LoneShock, NoiseBurst, ScriptedOperation, ScriptedStream
from service.acquisition.trigger import (INCOMPLETE, NEXT_OPERATION, TriggerDetector,
                                         TriggerSettings)

from .conftest import run_detector

FS = 128_000.0


def test_lone_shocks_noise_burst_and_clipped_shock_give_no_capture(breaker, settings):
    stream = ScriptedStream(
        breaker, duration_s=3.0, seed=5, operations=[],
        shocks=[LoneShock(0.3, 120.0), LoneShock(0.9, 700.0, 1900.0), LoneShock(1.5, 3000.0),
                LoneShock(1.502, 400.0)],
        bursts=[NoiseBurst(2.0, 0.08, vibration_sd_g=150.0, travel_sd_rad=0.01)])
    _, vib = stream.samples(int(1.5 * FS), int(1.51 * FS))
    assert np.max(np.abs(vib)) >= 999.0  # the big shock really clips
    found, _ = run_detector(stream, settings)
    assert found == []


def test_operation_among_disturbances_is_found_once(breaker, settings):
    stream = ScriptedStream(
        breaker, duration_s=1.5, seed=6, operations=[ScriptedOperation("open", 0.5)],
        shocks=[LoneShock(0.44, 300.0), LoneShock(0.65, 300.0)], bursts=[NoiseBurst(1.0, 0.05)])
    found, _ = run_detector(stream, settings)
    assert [op.operation for op in found] == ["open"]
    assert abs(found[0].window_start_s - stream.truth[0].t_shock_s) < 0.5e-3


def test_operation_straddling_a_gap_is_captured_but_flagged_incomplete(breaker, settings):
    ops = [ScriptedOperation("open", 0.3), ScriptedOperation("close", 1.0)]
    stream = ScriptedStream(breaker, duration_s=1.6, seed=7, operations=ops,
                            gaps=[Gap(0.32, 0.004)])  # 4 ms lost in the middle of the opening
    assert [t.incomplete for t in stream.truth] == [True, False]
    found, _ = run_detector(stream, settings)
    assert [op.operation for op in found] == ["open", "close"]
    opening, closing = found
    assert INCOMPLETE in opening.flags and INCOMPLETE in opening.capture.flags
    assert INCOMPLETE not in closing.flags
    gaps = opening.capture.meta["gaps"]
    assert gaps == [(int(round(0.32 * FS)), int(round(0.004 * FS)))]
    assert np.all(np.isfinite(opening.capture.travel))
    # The capture keeps the true sample positions: nothing after the gap is shifted.
    assert abs(opening.window_start_s - stream.truth[0].t_shock_s) < 0.5e-3
    assert abs(opening.window_end_s - stream.truth[0].t_end_s) < 1e-3


def test_gap_longer_than_the_ring_buffer_is_survived(breaker, settings):
    ops = [ScriptedOperation("open", 0.3), ScriptedOperation("close", 3.0)]
    stream = ScriptedStream(breaker, duration_s=3.5, seed=8, operations=ops, gaps=[Gap(0.33, 2.0)])
    found, detector = run_detector(stream, settings)
    assert [op.operation for op in found] == ["open", "close"]
    assert INCOMPLETE in found[0].flags and INCOMPLETE not in found[1].flags
    assert found[0].capture.travel.size < detector.buffer_samples


@pytest.mark.parametrize("trip_delay_s", [0.01, 0.03])
def test_o_co_sequence_alone(breaker, settings, trip_delay_s):
    ops = [ScriptedOperation("open", 0.2), ScriptedOperation("close", 0.5),
           ScriptedOperation("open", None, delay_s=trip_delay_s)]
    stream = ScriptedStream(breaker, duration_s=1.0, seed=9, operations=ops)
    found, _ = run_detector(stream, settings)
    assert [op.operation for op in found] == ["open", "close", "open"]
    closing = found[1]
    # The closing's capture stops before the trip's motion instead of running into it.
    assert (NEXT_OPERATION in closing.flags) == (trip_delay_s < settings.post_s)
    end_of_capture = (closing.capture.first_sample_index + closing.capture.travel.size) / FS
    assert end_of_capture < stream.truth[2].t_motion_s + 2e-3
    for op, t in zip(found, stream.truth):
        assert abs(op.window_start_s - t.t_shock_s) < 0.5e-3


def test_memory_is_bounded_regardless_of_stream_length(settings):
    rng = np.random.default_rng(1)
    travel = 1e-3 * rng.standard_normal(8192)
    vibration = 0.6 * rng.standard_normal(8192)
    detector = TriggerDetector(settings, FS)
    sizes = []
    for i in range(2000):  # 16.4 M samples: about 2 min of stream
        detector.feed(SampleBlock(i * 8192, travel, vibration, FS))
        if i in (10, 1999):
            ring = detector.ring
            sizes.append((detector.buffer_samples, ring.travel.size, ring.vibration.size, ring.valid.size))
    assert sizes[0] == sizes[1]
    assert sizes[0][0] < 0.5 * FS  # well under half a second of samples
    assert detector.ring.end == 2000 * 8192


def test_many_gaps_do_not_accumulate(settings):
    detector = TriggerDetector(settings, FS)
    zeros = np.zeros(1000)
    for i in range(3000):  # a gap before every block
        detector.feed(SampleBlock(i * 2000, zeros, zeros, FS))
    assert len(detector._gaps) <= detector.buffer_samples // 1000 + 1


def test_counter_going_back_restarts_without_stitching(breaker, settings):
    stream = ScriptedStream(breaker, duration_s=0.6, seed=10, operations=[ScriptedOperation("open", 0.2)])
    detector = TriggerDetector(settings, FS)
    found = []
    for block in stream.blocks(4096):
        found += detector.feed(block)
    # The DAQ restarts its sample counter: the same recording again from index 0.
    for block in stream.blocks(4096):
        found += detector.feed(block)
    found += detector.flush()
    assert len(found) == 2
    assert found[0].shock_index == found[1].shock_index
    assert abs(found[0].shock_index - stream.truth[0].shock_index) <= 3


def test_wrong_sample_rate_and_bad_settings_are_refused(settings):
    detector = TriggerDetector(settings, FS)
    with pytest.raises(ValueError, match="Hz"):
        detector.feed(SampleBlock(0, np.zeros(10), np.zeros(10), 64_000.0))
    with pytest.raises(ValueError, match="motion_fraction"):
        TriggerSettings(motion_fraction=1.5)
    with pytest.raises(ValueError, match="sample rate"):
        TriggerDetector(settings, float("nan"))


def test_settings_come_from_the_breaker_file(breaker):
    s = TriggerSettings.from_breaker(breaker, post_s=0.05)
    assert s.shock_threshold_g == breaker.acquisition["shock_threshold_g"]
    assert s.motion_fraction == breaker.acquisition["motion_fraction"]
    assert s.stroke_rad == breaker.stroke and s.post_s == 0.05
