"""Driver → trigger → durable COMTRADE files: the acquisition loop the service runs.

A capture is handed on (``on_capture``) only after its files are written, fsynced and renamed
into place, so a crash never leaves a queued job pointing at a half-written file.
"""

from __future__ import annotations

import asyncio
import dataclasses
import inspect
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from pathlib import Path

from drivers.capture import Capture
from .comtrade_writer import write_comtrade
from .recording import detect_capture
from .trigger import DetectedOperation, TriggerDetector, TriggerSettings

CAPTURE_FLAG = "capture"  # SampleBlock flag: a whole DAQ-triggered capture (Modbus), not a stream slice
NO_VIBRATION_FLAG = "no_vibration"  # SampleBlock flag: the source has no vibration channel


@dataclass
class CaptureStats:
    """Counters of one acquisition run.

    Attributes
    ----------
    blocks, samples : int
        Blocks and samples read from the driver.
    gaps : int
        Jumps forward in the sample index (lost samples).
    lost_samples : int
        Samples missing in those jumps.
    captures : int
        Operations written to disk.
    incomplete : int
        Of those, captures flagged ``incomplete``.
    by_operation : dict
        Captures per operation (``open``/``close``).
    files : list of Path
        The .cfg files written, in order.
    """

    blocks: int = 0
    samples: int = 0
    gaps: int = 0
    lost_samples: int = 0
    captures: int = 0
    incomplete: int = 0
    by_operation: dict = field(default_factory=dict)
    files: list = field(default_factory=list)


def capture_name(detected: DetectedOperation, prefix: str = "op") -> str:
    """File stem of a capture: its operation and stream sample index of the shock."""
    return f"{prefix}-{detected.shock_index:012d}-{detected.operation}"


async def capture_stream(driver, detector: TriggerDetector | TriggerSettings, out_dir: str | Path, *,
                         on_capture: Callable | None = None, fmt: str = "BINARY",
                         prefix: str = "op", station: str = "hvcb",
                         max_captures: int | None = None,
                         clock: Callable[[], datetime] | None = None) -> CaptureStats:
    """Read blocks from ``driver`` until it ends, writing each detected operation durably.

    Parameters
    ----------
    driver : async iterator of SampleBlock
        Any driver (serial stream, Modbus, replay) or an async generator.
    detector : TriggerDetector or TriggerSettings
        With settings, a detector is made at the first block's sample rate.
    out_dir : path
        Where the COMTRADE files go.
    on_capture : callable, optional
        ``on_capture(cfg_path, detected)``, plain or async; called after the files are durable.
    fmt : str
        COMTRADE data format (``BINARY`` default, ``ASCII``, ``BINARY32``, ``FLOAT32``).
    max_captures : int, optional
        Stop after this many captures (the driver is closed if it can be).
    clock : callable, optional
        ``clock()`` -> aware UTC datetime. A capture without a start time (a DAQ carries none)
        is stamped ``clock() - duration`` (the wall clock at its first sample, to within the
        transport latency), so the time travels with the file (edge agent → central server).
    """
    out_dir = Path(out_dir)
    stats = CaptureStats()
    expected = None

    async def emit(found):
        for det in found:
            if clock is not None and det.capture.start_time is None:
                start = clock() - timedelta(seconds=det.capture.duration)
                det = dataclasses.replace(det, capture=dataclasses.replace(det.capture, start_time=start))
            path = await asyncio.to_thread(write_comtrade, det.capture, out_dir,
                                           capture_name(det, prefix), format=fmt, station=station)
            stats.captures += 1
            stats.files.append(path)
            stats.by_operation[det.operation] = stats.by_operation.get(det.operation, 0) + 1
            if "incomplete" in det.flags:
                stats.incomplete += 1
            if on_capture is not None:
                result = on_capture(path, det)
                if inspect.isawaitable(result):
                    await result

    try:
        async for block in driver:
            if NO_VIBRATION_FLAG in block.flags:
                raise ValueError("the source has no vibration channel: the trigger needs the "
                                 "latch-release shock to find operations")
            if isinstance(detector, TriggerSettings):
                detector = TriggerDetector(detector, block.sample_rate)
            stats.blocks += 1
            stats.samples += block.travel.size
            if expected is not None and block.first_sample_index > expected:
                stats.gaps += 1
                stats.lost_samples += block.first_sample_index - expected
            expected = block.end_index
            if CAPTURE_FLAG in block.flags:
                # A DAQ-triggered capture stands alone: judge it whole, not as part of a stream.
                found = detector.flush() + _detect_block(block, detector.settings)
            else:
                found = detector.feed(block)
            await emit(found)
            release = getattr(driver, "release", None)
            if release is not None:  # the block's captures are durable: the DAQ may free them
                await release()
            if max_captures is not None and stats.captures >= max_captures:
                break
        if isinstance(detector, TriggerDetector):
            await emit(detector.flush())
    finally:
        close = getattr(driver, "aclose", None)
        if close is not None:
            await close()
    return stats


def _detect_block(block, settings: TriggerSettings) -> list[DetectedOperation]:
    capture = Capture(travel=block.travel, sample_rate=block.sample_rate, vibration=block.vibration,
                      first_sample_index=block.first_sample_index, source="daq-capture")
    return detect_capture(capture, settings)


__all__ = ["CaptureStats", "capture_name", "capture_stream", "detect_capture"]


async def capture_records(paths, breaker, out_dir: str | Path, *, on_capture: Callable | None = None,
                          fmt: str = "BINARY", prefix: str = "op", station: str = "hvcb") -> CaptureStats:
    """Capture files that are whole records (a breaker analyser's exports: coil currents, travel
    in mm, no vibration channel): each operation found in them (``detect_capture``'s coil path)
    is written as COMTRADE and handed on like a triggered capture. The replay of an edge agent
    uses it for analyser exports; the files are read with the breaker's channel mapping."""
    from .capture_file import breaker_reading, read_capture
    from .recording import detect_capture
    from .trigger import TriggerSettings

    out_dir = Path(out_dir)
    stats = CaptureStats()
    settings = TriggerSettings.from_breaker(breaker)
    for path in paths:
        record = await asyncio.to_thread(read_capture, path, **breaker_reading(breaker))
        for det in detect_capture(record, settings):
            name = f"{prefix}-{Path(path).stem}-{det.shock_index:08d}-{det.operation}"
            out = await asyncio.to_thread(write_comtrade, det.capture, out_dir, name, format=fmt, station=station)
            stats.captures += 1
            stats.files.append(out)
            stats.by_operation[det.operation] = stats.by_operation.get(det.operation, 0) + 1
            if on_capture is not None:
                result = on_capture(out, det)
                if inspect.isawaitable(result):
                    await result
    return stats
