"""The fitted parameters' names and units: the one mapping every page, file and answer uses.

From the nomenclature of docs/models.md (Yan et al. 2026, Section 2): each parameter is a
stiffness, resistance or damping term divided by an inertia, so its unit follows from that
quotient (N·m/rad ÷ kg·m² = s⁻²; N·m·s/rad ÷ kg·m² = s⁻¹; an inertia ratio has none).
"""

from __future__ import annotations

OPENING = ("AO", "BO", "DO", "EO")
CLOSING = ("AC", "BC", "CC")

UNITS = {
    "AO": "s⁻²",  # kO·rO²/J2: opening spring stiffness factor
    "BO": "s⁻²",  # (kO·xO1·rO − TOf)/J2: opening resistance factor
    "CO": "s⁻¹",  # caec·raec²/J2: puffer damping factor (structural)
    "DO": "s⁻¹",  # cb·rb²/J2: buffer damping factor
    "EO": "s⁻²",  # kb·rb²/J2: buffer stiffness factor
    "AC": "s⁻²",  # kC·rC·d/J1: closing spring stiffness factor
    "BC": "–",    # J2/J1: inertia factor (a ratio)
    "CC": "s⁻²",  # (TCf + kO·xO0·rO)/J2: closing resistance factor
    "DC": "s⁻²",  # kO·rO²/J2 = AO, seen while closing
    "latch_time_s": "s",  # the vibration's first shock to the start of motion (service.vibration), not fitted
    "buffer_ratio": "–",  # the vibration's buffer shock over the fitted travel's arrival at α0 (service.vibration)
}

# Each parameter in words (docs/models.md's table, shortened to what an engineer calls it).
NAMES = {
    "AO": "opening spring stiffness",
    "BO": "opening spring force",
    "CO": "puffer damping",
    "DO": "buffer damping",
    "EO": "buffer stiffness",
    "AC": "closing spring stiffness",
    "BC": "inertia ratio",
    "CC": "closing resistance",
    "DC": "opening spring stiffness seen while closing",
    "latch_time_s": "trip latch time",
    "buffer_ratio": "buffer shock timing against the travel",
}


def machine_unit(name: str) -> str:
    """``name``'s unit in ASCII for machine consumers (SCADA, IEC 61850): "s^-2", "s^-1", "1"."""
    return UNITS[name].replace("⁻²", "^-2").replace("⁻¹", "^-1").replace("–", "1")
