"""Issue 3 acceptance: 60 s stream, 12 operations (with an O–0.3 s–CO), 3 lone shocks, a noise
burst and a clipped latch shock."""

from __future__ import annotations

import numpy as np

from service.acquisition.trigger import VIBRATION_CLIPPED

from .conftest import run_detector


def test_twelve_captures_no_false_ones(acceptance):
    stream, found = acceptance
    assert len(stream.truth) == 12
    assert len(found) == 12
    assert [op.operation for op in found] == [t.operation for t in stream.truth]


def test_window_start_within_half_a_millisecond(acceptance):
    stream, found = acceptance
    errors = [abs(op.window_start_s - t.t_shock_s) for op, t in zip(found, stream.truth)]
    assert max(errors) < 0.5e-3, errors


def test_window_end_within_1ms_opening_3ms_closing(acceptance):
    stream, found = acceptance
    for op, t in zip(found, stream.truth):
        limit = 1e-3 if t.operation == "open" else 3e-3
        assert abs(op.window_end_s - t.t_end_s) < limit, (t.operation, op.window_end_s, t.t_end_s)


def test_o_co_sequence_gives_three_operations_in_order(acceptance):
    stream, found = acceptance
    in_sequence = [op for op in found if 19.9 < op.window_start_s < 20.6]
    assert [op.operation for op in in_sequence] == ["open", "close", "open"]
    starts = [op.window_start_s for op in in_sequence]
    assert starts == sorted(starts)
    assert abs(starts[1] - starts[0] - 0.3) < 1e-3


def test_captures_hold_the_window_and_are_flagged_only_when_clipped(acceptance, settings):
    stream, found = acceptance
    for op, t in zip(found, stream.truth):
        cap = op.capture
        first = cap.first_sample_index
        assert first <= op.shock_index - int(0.019 * stream.fs)  # 20 ms pre-trigger
        assert first + cap.travel.size > op.window_end_index      # the valid window is inside
        assert np.all(np.isfinite(cap.travel)) and cap.vibration.shape == cap.travel.shape
        assert (VIBRATION_CLIPPED in op.flags) == t.clipped
        assert "incomplete" not in op.flags
        w0, w1 = op.capture_window_s
        assert 0.019 < w0 < 0.021 and w1 > w0


def test_block_size_does_not_change_the_result(acceptance, settings):
    stream, found = acceptance
    again, _ = run_detector(stream, settings, block_samples=1000)
    assert [op.shock_index for op in again] == [op.shock_index for op in found]
    assert np.allclose([op.window_end_index for op in again], [op.window_end_index for op in found])
