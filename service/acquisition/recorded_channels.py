"""The channels a record holds besides the travel (coil currents, the travel as recorded, the
DCRM's resistance and current), and the instants the operation page marks on them.

Pure: a ``Capture`` in (its ``aux`` channels, in their own units), JSON-able dicts out.
"""

from __future__ import annotations

import numpy as np

from drivers.capture import Capture

from ..decimation import shared_minmax_indices
from ..mechanics.coordinates import operation_coordinate

# The position at which the travel characteristics count the contacts parting (opening) or
# touching (closing), as a fraction of the stroke (service.mechanics.characteristics).
CONTACT_FRACTION = {"open": 0.2, "close": 0.8}


def channel_indices(capture: Capture, points: int) -> np.ndarray:
    """Sample indices for drawing the travel and every recorded channel on one time axis: the
    one min/max decimator over all of them (no coil peak or DCRM step is lost)."""
    return shared_minmax_indices([capture.travel] + [a.data for a in capture.aux], points)


def recorded_channels(capture: Capture, idx, digits: int = 6) -> dict:
    """``{name: {"kind", "unit", "values"}}`` of the record's channels at sample indices ``idx``."""
    idx = np.asarray(idx, dtype=int)
    return {a.name: {"kind": a.kind, "unit": a.unit,
                     "values": [round(float(v), digits) for v in np.asarray(a.data, dtype=float)[idx]]}
            for a in capture.aux}


def _crossing(t, y, level: float, after: float, rising: bool) -> float | None:
    sel = (t >= after) & ((y >= level) if rising else (y <= level))
    hit = np.nonzero(sel)[0]
    return float(t[hit[0]]) if hit.size else None


def operation_events(capture: Capture, operation: str, stroke: float) -> dict:
    """The instants the page marks [s from the capture's first sample]: the coil command
    (``command_s``, from the record's coil currents) and the contacts parting (opening) or
    touching (closing), ``contact_s``, with ``contact_source`` saying how it was found.

    The contact instant is the DCRM's when a resistance channel is wired: where it crosses the
    geometric mean of its closed and open levels (the step spans decades: 48 µΩ to the 8000 µΩ
    range); otherwise the travel's crossing of ``CONTACT_FRACTION`` of the stroke, the point the
    travel characteristics count the operating time to.
    """
    t = capture.t
    command = capture.meta.get("command_s")
    start = float(command) if isinstance(command, (int, float)) else 0.0
    word = "part" if operation == "open" else "touch"
    out = {"command_s": float(command) if isinstance(command, (int, float)) else None,
           "command_source": capture.meta.get("command_source"), "contact_event": f"contact {word}",
           "contact_s": None, "contact_source": None}
    for r in capture.aux_of("resistance"):
        lo, hi = float(np.min(r.data)), float(np.max(r.data))
        if not (lo > 0 and hi > 2 * lo):
            continue
        level = float(np.sqrt(lo * hi))
        found = _crossing(t, r.data, level, start, rising=operation == "open")
        if found is not None:
            out["contact_s"], out["contact_source"] = found, f"DCRM {r.name} crossing {level:.4g} {r.unit}"
            return out
    y = operation_coordinate(capture.travel, operation, stroke)
    frac = CONTACT_FRACTION.get(operation, 0.5)
    found = _crossing(t, y, float(np.median(y[t <= start]) if np.any(t <= start) else y[0]) + frac * stroke,
                      start, rising=True)
    if found is not None:
        out["contact_s"], out["contact_source"] = found, f"travel at {frac:.0%} of the stroke"
    return out


def channel_plot(capture, operation: str, stroke: float, *, points: int = 2000) -> dict:
    """What the operation page draws under the travel: ``{"channels": {"t": [s], "series":
    {name: {kind, unit, values}}}, "events": ...}``, the channels min/max-decimated together to
    about ``points`` samples; ``{"channels": None, "events": None}`` for a capture without any
    (a DAQ's travel and vibration, or a pruned capture's preview)."""
    if not getattr(capture, "aux", ()):
        return {"channels": None, "events": None}
    idx = channel_indices(capture, points)
    return {"channels": {"t": [round(float(v), 7) for v in capture.t[idx]], "series": recorded_channels(capture, idx)},
            "events": operation_events(capture, operation, stroke)}
