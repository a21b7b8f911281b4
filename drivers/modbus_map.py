"""The Modbus capture-buffer register map (holding registers) and pure encode/decode helpers.

Modbus cannot stream 128 kS/s, so the DAQ triggers itself and holds its last capture in a
register-mapped buffer. Addresses are 0-based protocol addresses. Multi-register integers are
big-endian word order (high word first), the usual Modbus convention. The payload holds int16
codes, interleaved per sample (travel, vibration, travel, …), one code per register in two's
complement. The payload CRC-32 is ``zlib.crc32`` of those codes as little-endian int16 bytes —
the same bytes as a serial frame payload. Documented in config/modbus-registers.toml.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

MAP_VERSION = 1

# Header registers.
STATUS = 0              # 0 = empty (armed), 1 = capture ready
MAP_VERSION_REG = 1     # the DAQ's register map version
CAPTURE_ID = 2          # u16, increments per capture, wraps
CHANNELS = 3            # int16 codes per sample in the payload (2)
SAMPLES = 4             # u32, 2 registers: samples per channel in the capture
FIRST_SAMPLE_INDEX = 6  # u64, 4 registers: DAQ sample counter of the first sample
SAMPLE_RATE = 10        # u32, 2 registers [Hz]
PAYLOAD_CRC = 12        # u32, 2 registers: CRC-32 of the payload
ACK = 14                # write the capture id here: the DAQ frees the buffer
LOST_CAPTURES = 15      # u16: captures the DAQ discarded because the buffer was still full
HEADER_REGISTERS = 16   # registers 0..15 are read in one request

PAYLOAD_START = 256     # first payload register
REGISTER_SPACE = 65536
MAX_PAYLOAD_REGISTERS = REGISTER_SPACE - PAYLOAD_START
MAX_READ_REGISTERS = 125  # Modbus limit for one read of holding registers

STATUS_EMPTY = 0
STATUS_READY = 1


class RegisterMapError(ValueError):
    """Header registers that do not describe a valid capture."""


@dataclass(frozen=True)
class CaptureHeader:
    """What the header registers say about the held capture.

    Attributes
    ----------
    status : int
        ``STATUS_EMPTY`` or ``STATUS_READY``.
    capture_id : int
        u16 capture counter.
    channels : int
    samples : int
        Samples per channel.
    first_sample_index : int
    sample_rate_hz : int
        [Hz]
    payload_crc32 : int
    map_version : int
    lost_captures : int
    """

    status: int
    capture_id: int
    channels: int
    samples: int
    first_sample_index: int
    sample_rate_hz: int
    payload_crc32: int
    map_version: int = MAP_VERSION
    lost_captures: int = 0

    @property
    def ready(self) -> bool:
        return self.status == STATUS_READY

    @property
    def payload_registers(self) -> int:
        return self.samples * self.channels


def _words(value: int, n: int) -> list[int]:
    """Unsigned ``value`` as ``n`` registers, high word first."""
    return [(value >> (16 * (n - 1 - k))) & 0xFFFF for k in range(n)]


def _value(words) -> int:
    out = 0
    for w in words:
        out = (out << 16) | (int(w) & 0xFFFF)
    return out


def encode_header(h: CaptureHeader) -> list[int]:
    """The 16 header registers for ``h``."""
    regs = [0] * HEADER_REGISTERS
    regs[STATUS] = h.status
    regs[MAP_VERSION_REG] = h.map_version
    regs[CAPTURE_ID] = h.capture_id & 0xFFFF
    regs[CHANNELS] = h.channels
    regs[SAMPLES:SAMPLES + 2] = _words(h.samples, 2)
    regs[FIRST_SAMPLE_INDEX:FIRST_SAMPLE_INDEX + 4] = _words(h.first_sample_index, 4)
    regs[SAMPLE_RATE:SAMPLE_RATE + 2] = _words(h.sample_rate_hz, 2)
    regs[PAYLOAD_CRC:PAYLOAD_CRC + 2] = _words(h.payload_crc32, 2)
    regs[LOST_CAPTURES] = h.lost_captures & 0xFFFF
    return regs


def decode_header(regs) -> CaptureHeader:
    """Header registers → ``CaptureHeader``; a ready header is checked for plausibility.

    Raises
    ------
    RegisterMapError
        Wrong register count, unknown map version, or a ready capture that cannot fit the map.
    """
    regs = list(regs)
    if len(regs) != HEADER_REGISTERS:
        raise RegisterMapError(f"expected {HEADER_REGISTERS} header registers, got {len(regs)}")
    h = CaptureHeader(status=regs[STATUS], capture_id=regs[CAPTURE_ID], channels=regs[CHANNELS],
                      samples=_value(regs[SAMPLES:SAMPLES + 2]),
                      first_sample_index=_value(regs[FIRST_SAMPLE_INDEX:FIRST_SAMPLE_INDEX + 4]),
                      sample_rate_hz=_value(regs[SAMPLE_RATE:SAMPLE_RATE + 2]),
                      payload_crc32=_value(regs[PAYLOAD_CRC:PAYLOAD_CRC + 2]),
                      map_version=regs[MAP_VERSION_REG], lost_captures=regs[LOST_CAPTURES])
    if h.map_version != MAP_VERSION:
        raise RegisterMapError(f"the DAQ reports register map version {h.map_version}; "
                               f"this driver reads version {MAP_VERSION}")
    if h.status not in (STATUS_EMPTY, STATUS_READY):
        raise RegisterMapError(f"unknown capture status {h.status} in register {STATUS}")
    if h.ready:
        if h.channels < 2:
            raise RegisterMapError(f"a capture needs travel and vibration channels, header says {h.channels}")
        if not 0 < h.payload_registers <= MAX_PAYLOAD_REGISTERS:
            raise RegisterMapError(f"capture of {h.samples} samples x {h.channels} channels does not fit "
                                   f"the {MAX_PAYLOAD_REGISTERS}-register buffer")
        if h.sample_rate_hz <= 0:
            raise RegisterMapError("the capture header gives a sample rate of 0 Hz")
    return h


def encode_payload(codes) -> list[int]:
    """int16 codes, shape (samples, channels) → registers (uint16, interleaved per sample)."""
    codes = np.asarray(codes)
    if codes.ndim != 2:
        raise ValueError(f"codes must have shape (samples, channels), got {codes.shape}")
    return codes.astype(np.int16).ravel().view(np.uint16).tolist()


def decode_payload(regs, channels: int) -> np.ndarray:
    """Registers → int16 codes of shape (samples, channels)."""
    arr = np.asarray(regs, dtype=np.uint32)
    if arr.size % channels:
        raise RegisterMapError(f"{arr.size} payload registers are not a whole number of "
                               f"{channels}-channel samples")
    return arr.astype(np.uint16).view(np.int16).reshape(-1, channels)


def payload_crc32(codes) -> int:
    """CRC-32 of the payload: the codes as little-endian int16 bytes, interleaved per sample."""
    return zlib.crc32(np.asarray(codes).astype("<i2").tobytes())


def block_reads(n_registers: int, *, start: int = PAYLOAD_START,
                max_count: int = MAX_READ_REGISTERS) -> list[tuple[int, int]]:
    """The (address, count) reads that download ``n_registers`` payload registers."""
    if not 1 <= max_count <= MAX_READ_REGISTERS:
        raise ValueError(f"a Modbus read holds 1..{MAX_READ_REGISTERS} registers, got {max_count}")
    return [(start + k, min(max_count, n_registers - k)) for k in range(0, n_registers, max_count)]
