"""The serial stream frame: a pure codec, bytes in, frames out (no I/O).

Wire format, little-endian (see docs/serial-frame.md)::

    sync u32 | version u8 | channels u8 | samples u16 | sequence u32 | first_sample_index u64
    | int16 payload, interleaved per sample (ch0, ch1, ch0, ch1, ...) | CRC-32 u32

The sync word is the ASCII bytes ``b"HVCB"`` (u32 0x42435648). The CRC is ``zlib.crc32`` over
everything from the sync word through the payload.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

import numpy as np

SYNC = b"HVCB"
SYNC_WORD = struct.unpack("<I", SYNC)[0]  # 0x42435648
VERSION = 1
HEADER = struct.Struct("<4sBBHIQ")  # sync, version, channels, samples, sequence, first index
HEADER_SIZE = HEADER.size  # 20 bytes
CRC_SIZE = 4
OVERHEAD = HEADER_SIZE + CRC_SIZE  # 24 bytes per frame
DEFAULT_FRAME_SAMPLES = 256
MAX_FRAME_SAMPLES = 4096
SEQUENCE_MOD = 2**32


class FrameError(ValueError):
    """A frame cannot be built from the given values."""


@dataclass(frozen=True)
class Frame:
    """One decoded frame.

    Attributes
    ----------
    sequence : int
        Frame counter, modulo 2**32.
    first_sample_index : int
        DAQ sample counter of the frame's first sample.
    codes : ndarray of int16, shape (samples, channels)
        Raw converter codes, channel 0 = travel, channel 1 = vibration.
    version : int
    missing_before : int
        Frames lost between the previous decoded frame and this one (0 = contiguous); set by
        ``FrameDecoder``.
    """

    sequence: int
    first_sample_index: int
    codes: np.ndarray
    version: int = VERSION
    missing_before: int = 0

    @property
    def samples(self) -> int:
        return int(self.codes.shape[0])

    @property
    def channels(self) -> int:
        return int(self.codes.shape[1])

    @property
    def end_index(self) -> int:
        """Sample index one past the frame's last sample."""
        return self.first_sample_index + self.samples


def frame_size(samples: int, channels: int = 2) -> int:
    """Bytes on the wire for one frame."""
    return OVERHEAD + 2 * samples * channels


def encode_frame(codes, *, sequence: int, first_sample_index: int, version: int = VERSION) -> bytes:
    """Build one frame from int16 codes of shape (samples, channels)."""
    codes = np.asarray(codes)
    if codes.ndim != 2 or codes.shape[0] == 0 or not 1 <= codes.shape[1] <= 255:
        raise FrameError(f"codes must have shape (samples>0, 1..255 channels), got {codes.shape}")
    if codes.shape[0] > 0xFFFF:
        raise FrameError(f"a frame holds at most 65535 samples, got {codes.shape[0]}")
    if codes.dtype != np.int16:
        if np.any(codes < -32768) or np.any(codes > 32767):
            raise FrameError("codes out of int16 range")
    if not 0 <= first_sample_index < 2**64:
        raise FrameError(f"first_sample_index out of u64 range: {first_sample_index}")
    head = HEADER.pack(SYNC, version, codes.shape[1], codes.shape[0], sequence % SEQUENCE_MOD,
                       first_sample_index)
    body = head + codes.astype("<i2").tobytes()
    return body + struct.pack("<I", zlib.crc32(body))


class FrameDecoder:
    """Stateful decoder: ``feed(data)`` returns the complete, CRC-checked frames found so far.

    It hunts for the sync word, rejects absurd headers (unknown version, wrong channel count,
    zero or too many samples) and bad CRCs, and resumes at the next candidate sync. A frame whose
    sequence does not follow the previous one carries ``missing_before`` > 0, and the counters
    grow. Nothing it is fed makes it raise.

    Counters
    --------
    frames, crc_errors, bad_headers, resyncs (runs of skipped bytes), skipped_bytes,
    gaps (sequence discontinuities), dropped_frames (frames missing in those gaps).
    """

    def __init__(self, *, channels: int = 2, max_samples: int = MAX_FRAME_SAMPLES,
                 versions: tuple[int, ...] = (VERSION,)):
        if not 1 <= channels <= 255:
            raise ValueError(f"channels must be 1..255, got {channels}")
        if not 1 <= max_samples <= 0xFFFF:
            raise ValueError(f"max_samples must be 1..65535, got {max_samples}")
        self.channels = channels
        self.max_samples = max_samples
        self.versions = tuple(versions)
        self._buf = bytearray()
        self._last_sequence: int | None = None
        self._hunting = False
        self.frames = 0
        self.crc_errors = 0
        self.bad_headers = 0
        self.resyncs = 0
        self.skipped_bytes = 0
        self.gaps = 0
        self.dropped_frames = 0

    def reset_buffer(self) -> None:
        """Forget buffered partial bytes (after a reconnect); the sequence is still tracked."""
        self._buf.clear()

    def _skip(self, n: int) -> None:
        if n <= 0:
            return
        if not self._hunting:
            self._hunting = True
            self.resyncs += 1
        self.skipped_bytes += n
        del self._buf[:n]

    def feed(self, data: bytes) -> list[Frame]:
        """Add received bytes; return the frames completed by them, in order."""
        self._buf += data
        out: list[Frame] = []
        buf = self._buf
        while True:
            i = buf.find(SYNC)
            if i < 0:
                # Keep a possible partial sync word at the end.
                keep = next((k for k in (3, 2, 1) if buf.endswith(SYNC[:k])), 0)
                self._skip(len(buf) - keep)
                break
            self._skip(i)
            if len(buf) < HEADER_SIZE:
                break
            _, version, channels, samples, sequence, first = HEADER.unpack_from(buf, 0)
            if (version not in self.versions or channels != self.channels
                    or not 1 <= samples <= self.max_samples):
                self.bad_headers += 1
                self._skip(1)
                continue
            total = HEADER_SIZE + 2 * channels * samples + CRC_SIZE
            if len(buf) < total:
                break
            (crc,) = struct.unpack_from("<I", buf, total - CRC_SIZE)
            if zlib.crc32(memoryview(buf)[: total - CRC_SIZE]) != crc:
                self.crc_errors += 1
                self._skip(1)
                continue
            codes = np.frombuffer(bytes(buf[HEADER_SIZE: total - CRC_SIZE]), dtype="<i2")
            codes = codes.astype(np.int16).reshape(samples, channels)
            missing = 0
            if self._last_sequence is not None:
                jump = (sequence - self._last_sequence - 1) % SEQUENCE_MOD
                if jump:
                    self.gaps += 1
                    # A backwards jump is a DAQ restart or a replayed frame, not a known loss.
                    missing = jump if jump < SEQUENCE_MOD // 2 else 0
                    self.dropped_frames += missing
            self._last_sequence = sequence
            self._hunting = False
            self.frames += 1
            del buf[:total]
            out.append(Frame(sequence, first, codes, version, missing))
        return out
