"""Serial DAQ emulator: frames a sample stream and writes it to a pty or a TCP socket.

A driver connects to ``emulator.url``: the pty's slave device path, or ``socket://host:port``
(pyserial's TCP URL). Pace: real time (``speed=1``), N× real time, or unthrottled
(``speed=None``). Faults are injected on demand or by a ``FaultPlan``; every fault is counted in
``emulator.stats`` so a test can compare them with the driver's counters.
"""

from __future__ import annotations

import logging
import os
import select
import socket
import threading
import time
import tty
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np

from ..interface import SampleBlock
from ..scaling import ChannelScaling
from ..serial_frame import DEFAULT_FRAME_SAMPLES, HEADER_SIZE, SYNC, encode_frame

log = logging.getLogger("drivers.emulators.serial")

POLL_S = 0.05  # how often blocked loops look at the stop flag [s]


@dataclass
class FaultPlan:
    """Faults by frame sequence number, and/or every N frames (0 = never).

    ``corrupt``: one payload byte flipped (the frame fails its CRC and is lost);
    ``drop``: the frame is not sent (its sequence number is skipped);
    ``garbage``: random bytes without a sync word are sent before the frame;
    ``disconnect``: the TCP client is closed after the frame (socket links only).
    """

    corrupt: set = field(default_factory=set)
    drop: set = field(default_factory=set)
    garbage: set = field(default_factory=set)
    disconnect: set = field(default_factory=set)
    corrupt_every: int = 0
    drop_every: int = 0
    garbage_every: int = 0
    disconnect_every: int = 0

    def wants(self, kind: str, sequence: int) -> bool:
        every = getattr(self, f"{kind}_every")
        return sequence in getattr(self, kind) or (every > 0 and sequence > 0 and sequence % every == 0)


@dataclass
class SerialEmulatorStats:
    """What the emulator did, to compare with the driver's ``DriverStats``."""

    frames_sent: int = 0
    samples_sent: int = 0
    corrupted_frames: int = 0
    dropped_frames: int = 0
    garbage_bursts: int = 0
    disconnects: int = 0
    connections: int = 0
    client_losses: int = 0


class _LinkClosed(Exception):
    """The reader went away."""


class SerialDaqEmulator:
    """Streams ``source`` (SampleBlocks in physical units) as frames.

    Parameters
    ----------
    source : iterable of SampleBlock
    link : {"tcp", "pty"}
    scaling : ChannelScaling
        Physical units → int16 codes, as the real converter does.
    frame_samples : int
        Samples per frame (a shorter frame closes a block that is followed by an index jump).
    speed : float or None
        1 = real time at the source's sample rate, N = N× faster, None = as fast as possible.
    host, port : str, int
        TCP listen address; port 0 picks a free port.
    faults : FaultPlan, optional
    seed : int
        For the garbage bytes and the corrupted byte positions.
    """

    def __init__(self, source: Iterable[SampleBlock], *, link: str = "tcp",
                 scaling: ChannelScaling | None = None, frame_samples: int = DEFAULT_FRAME_SAMPLES,
                 speed: float | None = 1.0, host: str = "127.0.0.1", port: int = 0,
                 faults: FaultPlan | None = None, seed: int = 0, clock=time.monotonic):
        if link not in ("tcp", "pty"):
            raise ValueError(f"link must be 'tcp' or 'pty', got {link!r}")
        if speed is not None and not speed > 0:
            raise ValueError(f"speed must be positive or None (unthrottled), got {speed}")
        if not 1 <= frame_samples <= 4096:
            raise ValueError(f"frame_samples must be 1..4096, got {frame_samples}")
        self.link = link
        self.scaling = scaling or ChannelScaling()
        self.frame_samples = frame_samples
        self.speed = speed
        self.faults = faults or FaultPlan()
        self.stats = SerialEmulatorStats()
        self._source = iter(source)
        self._host, self._port = host, port
        self._clock = clock
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()
        self._pending = {"corrupt": 0, "drop": 0, "garbage": 0, "disconnect": 0}
        self._stop = threading.Event()
        self.done = threading.Event()  # set when the source is exhausted and all frames are out
        self._thread: threading.Thread | None = None
        self._listener: socket.socket | None = None
        self._client: socket.socket | None = None
        self._master = self._slave = None
        self._t0: float | None = None  # pacing origin [s] and the sample index it belongs to
        self._index0 = 0
        self.url = ""
        self._open()

    # -- lifecycle ------------------------------------------------------------------------------
    def _open(self) -> None:
        if self.link == "pty":
            self._master, self._slave = os.openpty()
            tty.setraw(self._slave)  # no newline or echo translation on the byte stream
            os.set_blocking(self._master, False)
            self.url = os.ttyname(self._slave)
        else:
            self._listener = socket.create_server((self._host, self._port))
            self._listener.setblocking(False)
            host, port = self._listener.getsockname()[:2]
            self.url = f"socket://{host}:{port}"
        log.info("serial DAQ emulator: connect the driver to %s", self.url)

    def start(self) -> "SerialDaqEmulator":
        """Start streaming in a writer thread."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f"serial-daq-emulator {self.url}",
                                            daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop the writer thread and close the pty or the sockets."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        for sock in (self._client, self._listener):
            if sock is not None:
                sock.close()
        for fd in (self._master, self._slave):
            if fd is not None:
                os.close(fd)
        self._client = self._listener = self._master = self._slave = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- fault injection on demand ---------------------------------------------------------------
    def inject(self, kind: str, count: int = 1) -> None:
        """Apply fault ``kind`` (corrupt, drop, garbage, disconnect) to the next ``count`` frames."""
        if kind not in self._pending:
            raise ValueError(f"unknown fault {kind!r}; choose from {sorted(self._pending)}")
        if kind == "disconnect" and self.link != "tcp":
            raise ValueError("disconnects are emulated on socket links only")
        with self._lock:
            self._pending[kind] += count

    def _take(self, kind: str, sequence: int) -> bool:
        with self._lock:
            if self._pending[kind] > 0:
                self._pending[kind] -= 1
                return True
        return self.faults.wants(kind, sequence)

    # -- frames ---------------------------------------------------------------------------------
    def _frames(self) -> Iterator[tuple[int, np.ndarray, float]]:
        """(first_sample_index, codes, sample_rate) per frame; a frame never spans an index jump."""
        pending: np.ndarray | None = None
        pending_first = 0
        fs = self.scaling.sample_rate_hz
        for block in self._source:
            codes = np.column_stack([self.scaling.travel_to_code(block.travel),
                                     self.scaling.vibration_to_code(block.vibration)])
            fs = block.sample_rate
            if pending is not None and pending_first + pending.shape[0] != block.first_sample_index:
                yield pending_first, pending, fs
                pending = None
            if pending is None:
                pending, pending_first = codes, block.first_sample_index
            else:
                pending = np.concatenate([pending, codes])
            n_full = pending.shape[0] // self.frame_samples * self.frame_samples
            for k in range(0, n_full, self.frame_samples):
                yield pending_first + k, pending[k:k + self.frame_samples], fs
            pending, pending_first = pending[n_full:], pending_first + n_full
            if pending.shape[0] == 0:
                pending = None
        if pending is not None:
            yield pending_first, pending, fs

    def _garbage(self) -> bytes:
        while True:
            junk = self._rng.integers(0, 256, int(self._rng.integers(1, 64)), dtype=np.uint8).tobytes()
            if SYNC not in junk and not any(junk.endswith(SYNC[:k]) for k in (1, 2, 3)):
                return junk

    def _run(self) -> None:
        try:
            self._stream()
        except _LinkClosed:
            pass
        finally:
            self.done.set()

    def _stream(self) -> None:
        sequence = 0
        for first, codes, fs in self._frames():
            if self._stop.is_set():
                return
            frame = encode_frame(codes, sequence=sequence, first_sample_index=first)
            if self.speed is not None:  # release each frame when its last sample would exist
                if self._t0 is None:
                    self._t0, self._index0 = self._clock(), first
                due = self._t0 + (first + codes.shape[0] - self._index0) / fs / self.speed
                wait = due - self._clock()
                if wait > 0 and self._stop.wait(wait):
                    return
            if self._take("drop", sequence):
                self.stats.dropped_frames += 1
            else:
                if self._take("corrupt", sequence):
                    buf = bytearray(frame)
                    pos = HEADER_SIZE + int(self._rng.integers(0, 2 * codes.size))
                    buf[pos] ^= 0xFF
                    frame = bytes(buf)
                    self.stats.corrupted_frames += 1
                if self._take("garbage", sequence):
                    frame = self._garbage() + frame
                    self.stats.garbage_bursts += 1
                if not self._send(frame):
                    return
                self.stats.frames_sent += 1
                self.stats.samples_sent += codes.shape[0]
                if self.link == "tcp" and self._take("disconnect", sequence):
                    self._drop_client()
                    self.stats.disconnects += 1
            sequence += 1

    # -- link -----------------------------------------------------------------------------------
    def _drop_client(self) -> None:
        if self._client is not None:
            try:
                self._client.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            self._client.close()
            self._client = None

    def _accept(self) -> bool:
        while not self._stop.is_set():
            ready, _, _ = select.select([self._listener], [], [], POLL_S)
            if ready:
                try:
                    client, addr = self._listener.accept()
                except BlockingIOError:
                    continue
                client.setblocking(False)
                self._client = client
                self._t0 = None  # pace from the connection on; no burst to catch up
                self.stats.connections += 1
                log.info("serial DAQ emulator %s: client %s connected", self.url, addr)
                return True
        return False

    def _send(self, data: bytes) -> bool:
        """Write the whole frame; on a socket, wait for a client and resend after a client loss.
        False when stopping."""
        while not self._stop.is_set():
            if self.link == "tcp" and self._client is None and not self._accept():
                return False
            try:
                self._write_all(data)
                return True
            except (BrokenPipeError, ConnectionResetError):
                self.stats.client_losses += 1
                self._drop_client()
        return False

    def _write_all(self, data: bytes) -> None:
        view = memoryview(data)
        fd = self._master if self.link == "pty" else self._client
        while view and not self._stop.is_set():
            _, ready, _ = select.select([], [fd], [], POLL_S)
            if not ready:
                continue
            try:
                n = os.write(fd, view) if self.link == "pty" else fd.send(view)
            except BlockingIOError:
                continue
            view = view[n:]
