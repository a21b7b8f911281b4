"""`incomplete` means samples are missing, nothing else (issue 21, item 6).

The demo's emulated DAQ serves each operation as one triggered record that ends 30 ms after the
stroke; the detector's window runs 30 ms past the settling, so an opening that settles late
asked for more than the record holds. That is the recorder's choice, not a lost sample.
"""

from __future__ import annotations

import dataclasses
import itertools

import pytest

from drivers.interface import SampleBlock
from service.acquisition.recording import detect_capture
from service.acquisition.trigger import INCOMPLETE, TriggerDetector
from service.api.demo import DemoScript, history


@pytest.fixture(scope="module")
def demo_records(breaker):
    """The first 24 records the demo's DAQ serves (openings and closings, mild effects)."""
    return [(kind, cap) for _, kind, cap in itertools.islice(history(breaker, DemoScript()), 24)]


def test_the_demo_records_on_a_clean_link_are_never_flagged_incomplete(demo_records, settings):
    kinds = []
    for kind, cap in demo_records:
        found = detect_capture(cap, settings)
        assert len(found) == 1, f"{kind}: {len(found)} operations found"
        assert INCOMPLETE not in found[0].flags, (kind, found[0].flags)
        kinds.append(found[0].operation)
    assert {"open", "close"} <= set(kinds)


def test_a_record_that_stops_inside_the_stroke_is_incomplete(demo_records, settings):
    kind, cap = next(r for r in demo_records if r[0] == "open")
    (op,) = detect_capture(cap, settings)
    motion = int(op.shock_index - cap.first_sample_index) + int(0.010 * cap.sample_rate)
    cut = dataclasses.replace(cap, travel=cap.travel[:motion], vibration=cap.vibration[:motion])
    found = detect_capture(cut, settings)
    assert found and INCOMPLETE in found[0].flags


def test_a_live_stream_that_ends_inside_the_capture_window_is_incomplete(demo_records, settings):
    """Unlike a record, a stream promised more samples: ending early loses some of the window."""
    kind, cap = next(r for r in demo_records if r[0] == "open")
    (whole,) = detect_capture(cap, settings)
    wanted_end = whole.capture.first_sample_index + whole.capture.travel.size
    short = wanted_end - cap.first_sample_index - int(0.010 * cap.sample_rate)  # 10 ms short
    det = TriggerDetector(settings, cap.sample_rate)
    found = det.feed(SampleBlock(cap.first_sample_index, cap.travel[:short], cap.vibration[:short],
                                 cap.sample_rate))
    found += det.flush()
    assert len(found) == 1 and INCOMPLETE in found[0].flags


def test_a_gap_inside_a_record_is_incomplete(demo_records, settings):
    kind, cap = next(r for r in demo_records if r[0] == "open")
    fs = cap.sample_rate
    det = TriggerDetector(settings, fs)
    k = int(0.030 * fs)  # 30 ms in: mid-stroke
    found = det.feed(SampleBlock(0, cap.travel[:k], cap.vibration[:k], fs))
    found += det.feed(SampleBlock(k + 64, cap.travel[k + 64:], cap.vibration[k + 64:], fs))
    found += det.flush(record=True)
    assert len(found) == 1 and INCOMPLETE in found[0].flags
