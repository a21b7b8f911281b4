"""An operation capture: the travel and vibration channels of one recording, in our units."""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime

import numpy as np


class CaptureError(ValueError):
    """A capture cannot be used: the message says why, for an engineer."""


@dataclass(frozen=True)
class AuxChannel:
    """A recorded channel besides travel and vibration, in its own unit: a coil current [A], a
    contact travel [mm] as recorded, a dynamic contact resistance [µΩ] or its test current [A]."""

    name: str
    kind: str
    unit: str
    data: np.ndarray


@dataclass(frozen=True)
class Capture:
    """Uniformly sampled travel (and optionally vibration) of one recording.

    Attributes
    ----------
    travel : ndarray
        Output-shaft angle measured from the closed position [rad].
    sample_rate : float
        [Hz].
    vibration : ndarray or None
        Mechanism acceleration [g].
    start_time : datetime or None
        Time of the first sample (UTC when known).
    source : str
        Where it came from (a path, a driver name).
    flags : tuple of str
        Acquisition flags, e.g. ``incomplete`` when it spans a stream gap.
    first_sample_index : int
        Index of the first sample in the acquisition stream, when known.
    travel_limits : tuple of float or None
        The travel channel's representable range [rad], for saturation checks.
    vibration_limits : tuple of float or None
        The vibration channel's representable range [g].
    meta : dict
        JSON-able notes: ``warnings``, and for analyser exports ``analyser`` (profile, header
        metadata, the analyser's own results) and ``travel_map``.
    aux : tuple of AuxChannel
        Other wired channels (coil currents, the travel as recorded, DCRM), sample-aligned.
    """

    travel: np.ndarray
    sample_rate: float
    vibration: np.ndarray | None = None
    start_time: datetime | None = None
    source: str = ""
    flags: tuple = ()
    first_sample_index: int = 0
    travel_limits: tuple | None = None
    vibration_limits: tuple | None = None
    meta: dict = field(default_factory=dict)
    aux: tuple = ()

    def aux_of(self, kind: str) -> list:
        """The auxiliary channels of one kind (``coil_current``, ``travel`` ...)."""
        return [a for a in self.aux if a.kind == kind]

    @property
    def t(self) -> np.ndarray:
        """Sample times from the first sample [s]."""
        return np.arange(self.travel.size) / self.sample_rate

    @property
    def duration(self) -> float:
        """[s]"""
        return self.travel.size / self.sample_rate
