"""What the vibration adds to a fit's characteristics: the latch time and the events (JSON-ready)."""

from __future__ import annotations

import numpy as np

from .coils import record_coils
from .events import VibrationError, detect_events
from .fingerprint import envelope


def vibration_characteristics(capture, operation: str, t_motion_s: float, t_end_s: float | None = None) -> dict:
    """``latch_time_s`` [s] (None with ``latch_time_reason`` in words), ``vibration_events``, the
    detection's noise and threshold, ``vibration_envelope`` (the fingerprint's grid) and, for a record
    with coil currents, ``coils`` (service.vibration.coils) for one operation of ``capture`` (a ``drivers.capture.Capture``).

    ``t_motion_s`` is the start of shaft motion from the travel fit (window start + onset delay)
    [s from the capture's first sample]; ``t_end_s`` the travel's end [s].

    Raises
    ------
    VibrationError
        The vibration channel does not match the capture (another length): the message names
        the capture.
    """
    vib = capture.vibration
    if vib is not None and np.asarray(vib).size != np.asarray(capture.travel).size:
        raise VibrationError(f"{capture.source or 'capture'}: the vibration channel has {np.asarray(vib).size} "
                             f"samples but the travel {np.asarray(capture.travel).size}: they are not one recording")
    out = detect_events(vib, capture.sample_rate, t_motion_s, operation, t_end_s=t_end_s,
                        limits=capture.vibration_limits, source=capture.source or "capture").to_characteristics()
    if out.get("vibration_events"):
        out["vibration_envelope"] = envelope(vib, capture.sample_rate, t_motion_s)
    coils = record_coils(capture) if getattr(capture, "aux", ()) else []
    if coils:
        out["coils"] = coils
    return out


def unread(reason: str) -> dict:
    """The characteristics of a vibration that could not be read at all."""
    return {"latch_time_s": None, "latch_time_reason": reason, "vibration_events": []}
