"""Progress bars: drawn on a terminal, silent otherwise."""

import io
import os
import pty

from service.progress import progress, track


def test_quiet_when_not_a_tty():
    out = io.StringIO()
    assert list(track(range(5), desc="fits", stream=out)) == [0, 1, 2, 3, 4]
    assert out.getvalue() == ""


def _drain(fd) -> str:
    """Everything written to the pty so far (the writes may arrive in several reads)."""
    import select

    chunks = []
    while select.select([fd], [], [], 0.5)[0]:
        try:
            data = os.read(fd, 65536)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    return b"".join(chunks).decode(errors="replace")


def test_rate_and_time_left_on_a_terminal():
    master, slave = pty.openpty()
    try:
        with os.fdopen(slave, "w", closefd=False) as stream:
            bar = progress(10, desc="refit 1", unit="fit", stream=stream)
            bar.update(4)
            bar.refresh()
            bar.close()
        text = _drain(master)
    finally:
        os.close(master)
        os.close(slave)
    assert "refit 1" in text and "4/10" in text and "fit/s" in text
    assert "<" in text  # elapsed<remaining


def test_study_pool_map_keeps_task_order_and_results():
    from service.studies.common import pool_map

    assert pool_map(abs, [-3, 2, -1], workers=1) == [3, 2, 1]


def test_detect_reports_every_sample_of_a_long_recording(breaker):
    """``hvcb detect``'s bar is driven by the detector: the counts add up to the recording."""
    from drivers.capture import Capture
    from drivers.emulators.sources import synthetic_stream
    from service.acquisition.recording import detect_capture
    from service.acquisition.trigger import TriggerSettings

    import numpy as np

    blocks = list(synthetic_stream(breaker, operations=("open", "close"), idle_s=0.05, seed=4))
    travel = np.concatenate([b.travel for b in blocks])
    vibration = np.concatenate([b.vibration for b in blocks])
    rec = Capture(travel=travel, vibration=vibration, sample_rate=blocks[0].sample_rate, source="stream")
    told = []
    found = detect_capture(rec, TriggerSettings.from_breaker(breaker), block_samples=10_000,
                           on_progress=told.append)
    assert sum(told) == travel.size and len(told) == -(-travel.size // 10_000)
    assert [op.operation for op in found] == ["open", "close"]
