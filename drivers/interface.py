"""The one interface every DAQ driver offers: an async iterator of sample blocks."""

from __future__ import annotations

from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class SampleBlock:
    """Consecutive samples of both channels.

    Attributes
    ----------
    first_sample_index : int
        Index of the first sample in the DAQ's own sample counter, so time is exact and a gap
        between blocks is visible as a jump in the index.
    travel : ndarray of float
        Output-shaft angle from the closed position [rad].
    vibration : ndarray of float
        Mechanism acceleration [g].
    sample_rate : float
        [Hz]
    flags : frozenset of str
        ``capture``: the block is a whole DAQ-triggered capture (Modbus), not a stream slice.
    """

    first_sample_index: int
    travel: np.ndarray
    vibration: np.ndarray
    sample_rate: float
    flags: frozenset = field(default_factory=frozenset)

    def __post_init__(self):
        if self.travel.shape != self.vibration.shape or self.travel.ndim != 1:
            raise ValueError("a sample block needs 1-D travel and vibration arrays of equal length")

    @property
    def end_index(self) -> int:
        """Index one past the last sample."""
        return self.first_sample_index + self.travel.size


@dataclass
class DriverStats:
    """Counters a driver keeps; the service exports them as metrics."""

    frames: int = 0
    samples: int = 0
    crc_errors: int = 0
    dropped_frames: int = 0
    resyncs: int = 0
    gaps: int = 0
    reconnects: int = 0
    retries: int = 0
    captures: int = 0
    connected: bool = False
    abandoned: int = 0  # capture downloads given up after bounded retries (Modbus)


@runtime_checkable
class Driver(Protocol):
    """A DAQ driver: ``async for block in driver: ...``; ``await driver.aclose()`` stops it.

    A driver whose DAQ holds data until told (Modbus capture buffer) also has
    ``async release()``: the consumer calls it once the last block is durable.
    """

    stats: DriverStats

    def __aiter__(self) -> AsyncIterator[SampleBlock]: ...

    async def aclose(self) -> None: ...
