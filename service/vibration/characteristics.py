"""What the vibration adds to a fit's characteristics: the latch time and the events (JSON-ready)."""

from __future__ import annotations

import numpy as np

from .coils import record_coils
from .events import VibrationError, detect_events
from .fingerprint import ENVELOPE_SPAN_S, envelope


def vibration_characteristics(capture, operation: str, t_motion_s: float, t_end_s: float | None = None, *,
                              model_travel=None, alpha0: float | None = None) -> dict:
    """``latch_time_s`` [s] (None with ``latch_time_reason`` in words), ``vibration_events``, the
    detection's noise and threshold, ``vibration_envelope`` (the fingerprint's grid) and, for a record
    with coil currents, ``coils`` (service.vibration.coils) for one operation of ``capture`` (a ``drivers.capture.Capture``).

    ``t_motion_s`` is the start of shaft motion from the travel fit (window start + onset delay)
    [s from the capture's first sample]; ``t_end_s`` the travel's end [s]. For an opening,
    ``model_travel`` (a callable giving the fitted model's travel [rad from closed] at the given
    times [s from the first sample]) and ``alpha0`` (the buffer engagement angle [rad]) give ``buffer_offset_s``: the
    vibration's buffer engagement minus the instant the fitted travel reaches α0 [s], the event
    shift the physics of the travel does not explain (a worn or loose buffer mount, a moved sensor).

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
    dropped = (getattr(capture, "meta", None) or {}).get("vibration_unread")
    if vib is None and dropped:  # the reader left a broken channel out (drivers.capture_file.check_finite)
        out = unread(str(dropped))
    else:
        read = detect_events(vib, capture.sample_rate, t_motion_s, operation, t_end_s=t_end_s,
                             limits=capture.vibration_limits, source=capture.source or "capture",
                             read_span_s=ENVELOPE_SPAN_S[1])
        out = read.to_characteristics()
        if out.get("vibration_events"):
            out["vibration_envelope"] = envelope(vib, capture.sample_rate, t_motion_s, banded=read.banded)
    if operation == "open" and model_travel is not None and alpha0 is not None:
        out.update(buffer_offset(out.get("vibration_events") or [], model_travel, capture.sample_rate,
                                 t_motion_s, alpha0, n=np.asarray(capture.travel).size))
    coils = record_coils(capture) if getattr(capture, "aux", ()) else []
    if coils:
        out["coils"] = coils
    return out


def unread(reason: str) -> dict:
    """The characteristics of a vibration that could not be read at all."""
    return {"latch_time_s": None, "latch_time_reason": reason, "vibration_events": []}


def buffer_offset(events: list, model_travel, sample_rate: float, t_motion_s: float, alpha0: float, *,
                  n: int) -> dict:
    """``buffer_offset_s`` [s]: the vibration's buffer engagement minus the fitted travel's arrival
    at ``alpha0`` [rad] (both from the start of motion), and ``buffer_ratio`` [-], the one over the
    other (1 when the travel explains the shock; the drift detector watches a positive quantity);
    None with ``buffer_offset_reason``.

    ``model_travel(t)``: the fitted travel [rad from closed] at times ``t`` [s from the first of the
    capture's ``n`` samples]. The opening's travel rises to α0 without turning back, so its first
    sample there is found on every ``COARSE``-th sample and then within the last step: the same
    sample as on the whole grid, for a ~COARSE-th of the model evaluations.
    """
    ev = next((e for e in events if e["name"] == "buffer_engagement"), None)
    if ev is None:
        return {"buffer_offset_s": None, "buffer_offset_reason": "no buffer engagement read from the vibration"}
    fs = float(sample_rate)
    coarse = np.arange(0, n, COARSE)
    reach = np.flatnonzero(np.asarray(model_travel(coarse / fs), dtype=float) >= alpha0)
    if reach.size == 0:
        last = np.arange(coarse[-1] + 1, n)  # the samples after the last coarse one
        fine = np.flatnonzero(np.asarray(model_travel(last / fs), dtype=float) >= alpha0) if last.size else last
        if fine.size == 0:
            return {"buffer_offset_s": None, "buffer_offset_reason": "the fitted travel never reaches the buffer"}
        first = int(last[fine[0]])
    else:
        k = int(coarse[reach[0]])
        step = np.arange(max(0, k - COARSE + 1), k + 1)
        first = int(step[np.flatnonzero(np.asarray(model_travel(step / fs), dtype=float) >= alpha0)[0]])
    t_model = first / fs - t_motion_s
    if t_model <= 0:
        return {"buffer_offset_s": None, "buffer_offset_reason": "the fitted travel starts inside the buffer"}
    return {"buffer_offset_s": float(ev["t_s"] - t_model), "buffer_ratio": float(ev["t_s"] / t_model)}


COARSE = 16
"""The buffer crossing's first search step [samples]."""
