"""Operations in a whole recording: the streaming trigger run over it block by block, or, for a
record without a vibration channel (a breaker analyser's), the coil-current detector.

Its own module so that ``trigger`` and ``coil_trigger`` need not import each other.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from datetime import timedelta

from drivers.capture import Capture
from drivers.interface import SampleBlock

from .coil_trigger import detect_from_coils  # an analyser record: coils give the command
from .trigger import DetectedOperation, TriggerDetector, TriggerSettings


def detect_capture(capture: Capture, settings: TriggerSettings, *, block_samples: int = 65_536,
                   on_progress: Callable[[int], None] | None = None) -> list[DetectedOperation]:
    """Run the detector over a whole recording; times refer to its first sample.

    ``on_progress(n)`` is told each time ``n`` more samples have been scanned.
    """
    if capture.vibration is None:
        if not capture.aux_of("coil_current"):
            raise ValueError(f"{capture.source or 'the recording'} has no vibration channel and no coil "
                             "currents: the trigger needs the latch-release shock or the command")
        if on_progress is not None:
            on_progress(capture.travel.size)
        return detect_from_coils(capture, settings)
    detector = TriggerDetector(settings, capture.sample_rate)
    found = []
    first = int(capture.first_sample_index)
    for i in range(0, capture.travel.size, block_samples):
        found += detector.feed(SampleBlock(first + i, capture.travel[i:i + block_samples],
                                           capture.vibration[i:i + block_samples], capture.sample_rate))
        if on_progress is not None:
            on_progress(min(block_samples, capture.travel.size - i))
    found += detector.flush(record=True)
    if capture.start_time is not None:
        found = [_with_start_time(op, capture) for op in found]
    return found


def _with_start_time(op: DetectedOperation, recording: Capture) -> DetectedOperation:
    offset = (op.capture.first_sample_index - recording.first_sample_index) / recording.sample_rate
    cap = replace(op.capture, start_time=recording.start_time + timedelta(seconds=offset),
                  source=recording.source or op.capture.source)
    return replace(op, capture=cap)
