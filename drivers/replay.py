"""Replay driver: plays recorded captures and long recorded streams back as sample blocks.

Sources: a COMTRADE (``.cfg``/``.cff``) or CSV (``t_s,travel_rad,vibration_g``) file, a
``Capture``, a list of those (played one after another), or an iterable / async iterable of
``SampleBlock``. CSV files are read in chunks, so a stream file of any length plays in bounded
memory. Pace: real time (``speed=1``), N× real time, or as fast as possible (``speed=None``).
The clock and the sleep are injected, so tests run without waiting.
"""

from __future__ import annotations

import asyncio
import io
import itertools
import time
from collections.abc import AsyncIterable, Iterable, Iterator
from pathlib import Path

import numpy as np

from drivers.capture import Capture, CaptureError
from drivers.capture_file import read_capture

from .interface import DriverStats, SampleBlock

NO_VIBRATION_FLAG = "no_vibration"  # the recording had no vibration channel; zeros stand in
CSV_CHUNK_ROWS = 65536


def capture_blocks(capture: Capture, block_samples: int, first_index: int) -> Iterator[SampleBlock]:
    """Split a capture into blocks starting at sample index ``first_index``."""
    flags = frozenset()
    vib = capture.vibration
    if vib is None:
        vib = np.zeros_like(capture.travel)
        flags = frozenset({NO_VIBRATION_FLAG})
    for k in range(0, capture.travel.size, block_samples):
        yield SampleBlock(first_index + k, np.asarray(capture.travel[k:k + block_samples], float),
                          np.asarray(vib[k:k + block_samples], float), capture.sample_rate, flags)


def csv_stream_blocks(path: str | Path, block_samples: int, first_index: int = 0) -> Iterator[SampleBlock]:
    """Read a ``t_s,travel_rad[,vibration_g]`` CSV in chunks; the sample rate comes from the
    time column of the first chunk.

    Raises
    ------
    CaptureError
        A bad header, non-numeric rows, or fewer than 2 samples.
    """
    path = Path(path)
    with path.open() as f:
        header = [h.strip().lower() for h in f.readline().split(",")]
        if header[:2] != ["t_s", "travel_rad"] or (len(header) > 2 and header[2] != "vibration_g"):
            raise CaptureError(f"{path}: expected a header 't_s,travel_rad[,vibration_g]', got {','.join(header)[:80]!r}")
        fs = None
        index = first_index
        pending = np.empty((0, len(header)))
        while True:
            lines = list(itertools.islice(f, CSV_CHUNK_ROWS))
            if lines:
                try:
                    data = np.loadtxt(io.StringIO("".join(lines)), delimiter=",", ndmin=2)
                except ValueError as exc:
                    raise CaptureError(f"{path}: not numeric CSV near sample {index}: {exc}") from None
                pending = np.vstack([pending, data]) if pending.size else data
            if fs is None:
                if pending.shape[0] < 2:
                    raise CaptureError(f"{path}: fewer than 2 samples")
                period = float(np.median(np.diff(pending[:, 0])))
                if not period > 0:
                    raise CaptureError(f"{path}: the time column must increase")
                fs = 1.0 / period
            n = pending.shape[0] if not lines else pending.shape[0] // block_samples * block_samples
            for k in range(0, n, block_samples):
                chunk = pending[k:k + block_samples]
                vib = chunk[:, 2] if chunk.shape[1] > 2 else np.zeros(chunk.shape[0])
                flags = frozenset() if chunk.shape[1] > 2 else frozenset({NO_VIBRATION_FLAG})
                yield SampleBlock(index, chunk[:, 1].copy(), vib.copy(), fs, flags)
                index += chunk.shape[0]
            pending = pending[n:]
            if not lines:
                return


class ReplayDriver:
    """Replays recordings as a driver: ``async for block in ReplayDriver(source, speed=10)``.

    Parameters
    ----------
    source : path, Capture, list of those, or (async) iterable of SampleBlock
    block_samples : int
        Samples per block for file and capture sources (larger incoming blocks are split).
    speed : float or None
        1 = real time, N = N× real time, None = as fast as possible.
    clock : callable
        Monotonic time [s] (injected in tests).
    sleep : coroutine function
        ``await sleep(seconds)`` (injected in tests).

    A block is released when its last sample would have been acquired: at
    ``t0 + (samples so far) / sample_rate / speed``. Captures in a list are placed one after
    another in the sample index (a capture's own first_sample_index is kept when it is later).
    """

    def __init__(self, source, *, block_samples: int = 4096, speed: float | None = 1.0,
                 clock=time.monotonic, sleep=asyncio.sleep):
        if block_samples < 1:
            raise ValueError(f"block_samples must be at least 1, got {block_samples}")
        if speed is not None and not speed > 0:
            raise ValueError(f"speed must be positive, or None for as fast as possible; got {speed}")
        self.block_samples = block_samples
        self.speed = speed
        self.stats = DriverStats()
        self._clock, self._sleep = clock, sleep
        self._closed = False
        self._t0: float | None = None
        self._elapsed = 0.0  # acquisition time of the samples released so far [s]
        if isinstance(source, AsyncIterable):
            self._async_blocks = source.__aiter__()
            self._blocks = None
        else:
            self._async_blocks = None
            self._blocks = self._split(self._sync_blocks(source))

    # -- sources --------------------------------------------------------------------------------
    def _sync_blocks(self, source) -> Iterator[SampleBlock]:
        if isinstance(source, (str, Path, Capture)):
            source = [source]
        items = list(source) if isinstance(source, (list, tuple)) else source
        next_index = 0
        for item in items:
            if isinstance(item, SampleBlock):
                yield item
                continue
            if isinstance(item, (str, Path)) and Path(item).suffix.lower() in (".csv", ".txt"):
                blocks = csv_stream_blocks(item, self.block_samples, next_index)
            elif isinstance(item, (str, Path)):
                cap = read_capture(item)
                blocks = capture_blocks(cap, self.block_samples, max(cap.first_sample_index, next_index))
            elif isinstance(item, Capture):
                blocks = capture_blocks(item, self.block_samples, max(item.first_sample_index, next_index))
            else:
                raise TypeError(f"replay cannot play a {type(item).__name__}; give a path, a Capture "
                                "or SampleBlocks")
            for block in blocks:
                next_index = block.end_index
                yield block

    def _split(self, blocks: Iterable[SampleBlock]) -> Iterator[SampleBlock]:
        n = self.block_samples
        for b in blocks:
            if b.travel.size <= n:
                yield b
                continue
            for k in range(0, b.travel.size, n):
                yield SampleBlock(b.first_sample_index + k, b.travel[k:k + n], b.vibration[k:k + n],
                                  b.sample_rate, b.flags)

    # -- driver ---------------------------------------------------------------------------------
    def __aiter__(self):
        return self

    async def __anext__(self) -> SampleBlock:
        if self._closed:
            raise StopAsyncIteration
        if self._blocks is not None:
            block = next(self._blocks, None)
        else:
            block = await anext(self._async_blocks, None)
        if block is None:
            self.stats.connected = False
            raise StopAsyncIteration
        self.stats.connected = True
        if self.speed is not None:
            if self._t0 is None:
                self._t0 = self._clock()
            self._elapsed += block.travel.size / block.sample_rate
            wait = self._t0 + self._elapsed / self.speed - self._clock()
            if wait > 0:
                await self._sleep(wait)
            if self._closed:
                raise StopAsyncIteration
        self.stats.frames += 1
        self.stats.samples += block.travel.size
        return block

    async def aclose(self) -> None:
        self._closed = True
        self.stats.connected = False
        if self._async_blocks is not None and hasattr(self._async_blocks, "aclose"):
            await self._async_blocks.aclose()
