"""Pipeline: driver blocks → trigger → durable COMTRADE files → on_capture."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from drivers.interface import SampleBlock
from service.acquisition.capture_file import read_capture
from service.acquisition.pipeline import CaptureStats, capture_stream
from drivers.stream_script import Gap, ScriptedOperation, ScriptedStream
from service.acquisition.trigger import TriggerDetector


@pytest.fixture(scope="module")
def stream(breaker):
    ops = [ScriptedOperation("open", 0.2), ScriptedOperation("close", 0.8)]
    return ScriptedStream(breaker, duration_s=1.3, seed=11, operations=ops, gaps=[Gap(1.2, 0.01)])


class ListDriver:
    """A minimal driver: yields given blocks, records aclose()."""

    def __init__(self, blocks):
        self._blocks = list(blocks)
        self.closed = False

    def __aiter__(self):
        return self._gen()

    async def _gen(self):
        for b in self._blocks:
            await asyncio.sleep(0)
            yield b

    async def aclose(self):
        self.closed = True


def test_each_capture_is_on_disk_before_it_is_handed_on(stream, settings, tmp_path):
    seen = []

    def on_capture(path, detected):
        # The files must already be complete and readable when the service is told.
        cap = read_capture(path)
        seen.append((path.name, detected.operation, cap.travel.size))

    driver = ListDriver(stream.blocks(2048))
    stats = asyncio.run(capture_stream(driver, TriggerDetector(settings, stream.fs), tmp_path,
                                       on_capture=on_capture))
    assert isinstance(stats, CaptureStats)
    assert [op for _, op, _ in seen] == ["open", "close"]
    assert stats.captures == 2 and stats.by_operation == {"open": 1, "close": 1}
    assert stats.gaps == 1 and stats.lost_samples == int(round(0.01 * stream.fs))
    assert stats.samples == stream.n_samples - stats.lost_samples
    assert [p.name for p in stats.files] == [name for name, _, _ in seen]
    assert driver.closed
    for path, (_, _, n) in zip(stats.files, seen):
        assert path.is_file() and path.with_suffix(".dat").is_file() and n > 0.08 * stream.fs


def test_async_callback_settings_detector_and_ascii(stream, settings, tmp_path):
    calls = []

    async def on_capture(path, detected):
        await asyncio.sleep(0)
        calls.append(path)

    stats = asyncio.run(capture_stream(ListDriver(stream.blocks(4096)), settings, tmp_path,
                                       on_capture=on_capture, fmt="ASCII", max_captures=1))
    assert stats.captures == 1 and len(calls) == 1
    assert "ASCII" in calls[0].read_text()


def test_daq_capture_blocks_are_judged_whole(stream, settings, tmp_path):
    # A Modbus DAQ delivers whole captures; each holds one operation.
    blocks = []
    for truth in stream.truth:
        i0 = int((truth.t_shock_s - 0.03) * stream.fs)
        i1 = int((truth.t_end_s + 0.06) * stream.fs)
        travel, vib = stream.samples(i0, i1)
        blocks.append(SampleBlock(i0, travel, vib, stream.fs, frozenset({"capture"})))
    stats = asyncio.run(capture_stream(ListDriver(blocks), TriggerDetector(settings, stream.fs), tmp_path))
    assert stats.by_operation == {"open": 1, "close": 1}


def test_source_without_vibration_is_refused(settings, tmp_path):
    block = SampleBlock(0, np.zeros(100), np.zeros(100), 128_000.0, frozenset({"no_vibration"}))
    with pytest.raises(ValueError, match="vibration"):
        asyncio.run(capture_stream(ListDriver([block]), settings, tmp_path))
