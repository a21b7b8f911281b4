"""Serial stream transport: pyserial in a reader thread, frames decoded into sample blocks.

The DAQ streams frames (``drivers.serial_frame``) over USB CDC, a fast UART, a pty or a TCP
socket (pyserial URL ``socket://host:port``). A reader thread owns the port: it opens it, reads,
decodes, scales and hands blocks to the event loop through a bounded queue. When the port
vanishes it reopens it with exponential backoff and counts a reconnect.
"""

from __future__ import annotations

import asyncio
import logging
import queue
import threading
from dataclasses import dataclass

import numpy as np
import serial

from .errors import DriverError
from .backoff import Backoff
from .interface import DriverStats, SampleBlock
from .scaling import ChannelScaling
from .serial_frame import MAX_FRAME_SAMPLES, Frame, FrameDecoder

log = logging.getLogger("drivers.serial")

GAP_FLAG = "gap"  # the block does not follow the previous one: samples were lost before it


@dataclass(frozen=True)
class SerialSettings:
    """How to reach a streaming DAQ.

    Attributes
    ----------
    url : str
        Device path (``/dev/ttyACM0``, a pty path) or a pyserial URL (``socket://host:port``).
    baudrate : int
        [bit/s]; ignored by USB CDC and sockets. A UART needs ≥ 6 Mbaud for 2 ch × 128 kS/s.
    read_timeout_s : float
        Longest wait for one read [s]; bounds the shutdown latency.
    read_size : int
        Largest read [bytes].
    reconnect_min_s, reconnect_max_s : float
        Backoff between reopen attempts, doubling from min to max [s].
    channels : int
        Channels per frame (2, or 3 with the optional camshaft channel, which is ignored here).
    max_frame_samples : int
        Frames announcing more samples are rejected as corrupt.
    queue_blocks : int
        Blocks buffered between the reader thread and the consumer.
    """

    url: str
    baudrate: int = 6_000_000
    read_timeout_s: float = 0.05
    read_size: int = 65536
    reconnect_min_s: float = 0.1
    reconnect_max_s: float = 5.0
    channels: int = 2
    max_frame_samples: int = MAX_FRAME_SAMPLES
    queue_blocks: int = 1024

    def __post_init__(self):
        if not self.url:
            raise ValueError("serial DAQ: give a device path or a URL such as socket://host:port")
        if not 0 < self.reconnect_min_s <= self.reconnect_max_s:
            raise ValueError("serial DAQ: need 0 < reconnect_min_s <= reconnect_max_s")
        if self.read_timeout_s <= 0 or self.read_size <= 0 or self.queue_blocks <= 0:
            raise ValueError("serial DAQ: read_timeout_s, read_size and queue_blocks must be positive")
        if self.channels < 2:
            raise ValueError("serial DAQ: frames need at least the travel and vibration channels")


class SerialStreamDriver:
    """Driver for a DAQ that streams frames: ``async for block in driver``.

    Each block holds the frames decoded from one read that follow each other without loss.
    A block after lost samples carries the ``gap`` flag; its ``first_sample_index`` jumps.
    ``stats`` counts frames, samples, CRC errors, dropped frames, resyncs, gaps and reconnects.
    """

    def __init__(self, settings: SerialSettings, scaling: ChannelScaling | None = None, *,
                 open_port=None):
        self.settings = settings
        self.scaling = scaling or ChannelScaling()
        self.stats = DriverStats()
        self.decoder = FrameDecoder(channels=settings.channels, max_samples=settings.max_frame_samples)
        self._open_port = open_port or self._default_open
        self._queue: queue.Queue = queue.Queue(maxsize=settings.queue_blocks)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._wake: asyncio.Event | None = None
        self._last_end: int | None = None

    # -- consumer side (event loop) ------------------------------------------------------------
    def __aiter__(self):
        if self._thread is None:
            self._loop = asyncio.get_running_loop()
            self._wake = asyncio.Event()
            self._thread = threading.Thread(target=self._run, name=f"serial-daq {self.settings.url}",
                                            daemon=True)
            self._thread.start()
        return self

    async def __anext__(self) -> SampleBlock:
        if self._thread is None:
            self.__aiter__()
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                if self._stop.is_set() or not self._thread.is_alive():
                    raise StopAsyncIteration from None
                self._wake.clear()
                if self._queue.empty():
                    await self._wake.wait()
                continue
            if isinstance(item, BaseException):
                raise item
            return item

    async def aclose(self) -> None:
        """Stop the reader thread and close the port."""
        self._stop.set()
        thread = self._thread
        while thread is not None and thread.is_alive():
            await asyncio.sleep(0.01)
        if self._wake is not None:
            self._wake.set()

    # -- reader thread --------------------------------------------------------------------------
    def _default_open(self):
        s = self.settings
        return serial.serial_for_url(s.url, baudrate=s.baudrate, timeout=s.read_timeout_s)

    def _signal(self) -> None:
        try:
            self._loop.call_soon_threadsafe(self._wake.set)
        except RuntimeError:  # the loop is closed: nobody is listening any more
            self._stop.set()

    def _put(self, item) -> None:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.05)
            except queue.Full:
                continue
            self._signal()
            return

    def _run(self) -> None:
        s = self.settings
        backoff = Backoff(s.reconnect_min_s, s.reconnect_max_s)
        opened_before = False
        failing = False
        while not self._stop.is_set():
            try:
                port = self._open_port()
            except ValueError as exc:  # malformed URL or settings: retrying cannot help
                self._put(DriverError(f"serial DAQ {s.url}: {exc}"))
                break
            except (serial.SerialException, OSError) as exc:
                if not failing:
                    log.warning("serial DAQ %s: cannot open (%s); retrying with backoff", s.url, exc)
                    failing = True
                self._stop.wait(backoff.next())
                continue
            failing = False
            backoff.reset()
            if opened_before:
                self.stats.reconnects += 1
            opened_before = True
            # A partial frame from the old link must not be spliced. (pyserial also flushed the
            # input on open: frames in flight are lost and the next block is flagged as a gap.)
            self.decoder.reset_buffer()
            self.stats.connected = True
            log.info("serial DAQ %s: connected", s.url)
            try:
                while not self._stop.is_set():
                    data = port.read(s.read_size)
                    if data:
                        self._handle(data)
            except (serial.SerialException, OSError) as exc:
                log.warning("serial DAQ %s: link lost (%s); reconnecting", s.url, exc)
            finally:
                self.stats.connected = False
                try:
                    port.close()
                except Exception:  # closing a dead port may fail too; nothing to recover
                    pass
            self._stop.wait(backoff.next())
        self._signal()

    def _handle(self, data: bytes) -> None:
        frames = self.decoder.feed(data)
        d, st = self.decoder, self.stats
        st.frames, st.crc_errors, st.dropped_frames = d.frames, d.crc_errors, d.dropped_frames
        st.resyncs = d.resyncs + d.bad_headers
        group: list[Frame] = []
        for frame in frames:
            if group and (frame.missing_before or frame.first_sample_index != group[-1].end_index):
                self._emit(group)
                group = []
            group.append(frame)
        if group:
            self._emit(group)

    def _emit(self, frames: list[Frame]) -> None:
        first = frames[0]
        codes = first.codes if len(frames) == 1 else np.concatenate([f.codes for f in frames])
        flags = frozenset()
        if self._last_end is not None and (first.missing_before or first.first_sample_index != self._last_end):
            flags = frozenset({GAP_FLAG})
            self.stats.gaps += 1
            log.warning("serial DAQ %s: %d frame(s) lost, sample index %d -> %d", self.settings.url,
                        first.missing_before, self._last_end, first.first_sample_index)
        self._last_end = frames[-1].end_index
        block = SampleBlock(first.first_sample_index, self.scaling.code_to_travel(codes[:, 0]),
                            self.scaling.code_to_vibration(codes[:, 1]), self.scaling.sample_rate_hz, flags)
        self.stats.samples += block.travel.size
        self._put(block)
