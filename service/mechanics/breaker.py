"""A breaker's structure and the model parameters it implies (Eqs. 8 and 12).

Pure data: reading a breaker file is done by ``service.breaker_file``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .cam_profile import CamProfile
from .closing import ClosingGeometry

OPENING_PARAMETERS = ("AO", "BO", "DO", "EO")
CLOSING_PARAMETERS = ("AC", "BC", "CC")

# Paper Table 2 search ranges: [s^-2], [s^-2], [s^-1], [s^-2], [s^-2], [-], [s^-2].
TABLE2_RANGES = {
    "AO": (2000.0, 3500.0), "BO": (4000.0, 6000.0), "DO": (10.0, 50.0), "EO": (4000.0, 6000.0),
    "AC": (18000.0, 23000.0), "BC": (1.0, 3.0), "CC": (8000.0, 12000.0),
}


@dataclass(frozen=True)
class Breaker:
    """One breaker type: structural constants, design state, cam table and channel mapping.

    Attributes (SI units)
    ----------
    name : str
    kC, xC0, d, rC, J1, theta1_start : closing spring–camshaft system [N/m, m, m, m, kg m², rad]
    kO, xO0, xO1, rO, J2, TCf, TOf : opening spring–output shaft system [N/m, m, m, m, kg m², N m, N m]
    caec, raec : puffer damping [N s/m] and arm [m]
    cb, kb, rb, alpha0 : buffer damping [N s/m], stiffness [N/m], arm [m], engagement angle [rad]
    cam : CamProfile
    stroke : float
        Output-shaft angle of the open rest position, measured from closed [rad].
    ranges : dict
        Initial CMA-ES search range per parameter.
    channels : dict
        COMTRADE channel names for ``travel`` and ``vibration``.
    travel_map : object or None
        How a contact travel recorded in mm maps to rad (``service.breaker_travel.TravelMap``).
    estimate_structure : tuple of str
        Structure an unknown design's opening fit estimates from the curve (``alpha0``).
    cam : CamProfile or None
        None for a design whose cam table is unknown: its closing cannot be modelled.
    """

    name: str
    kC: float
    xC0: float
    d: float
    rC: float
    J1: float
    theta1_start: float
    kO: float
    xO0: float
    xO1: float
    rO: float
    J2: float
    TCf: float
    TOf: float
    caec: float
    raec: float
    cb: float
    kb: float
    rb: float
    alpha0: float
    cam: CamProfile | None
    stroke: float = 1.0
    ranges: dict = field(default_factory=lambda: dict(TABLE2_RANGES))
    channels: dict = field(default_factory=lambda: {"travel": "travel", "vibration": "vibration"})
    acquisition: dict = field(default_factory=dict)
    travel_map: object = None
    estimate_structure: tuple = ()

    @property
    def CO(self) -> float:
        """Puffer damping factor caec·raec²/J2 [s^-1] (structural, not estimated)."""
        return self.caec * self.raec**2 / self.J2

    @property
    def closing_geometry(self) -> ClosingGeometry:
        return ClosingGeometry(self.xC0, self.rC, self.d, self.theta1_start)

    def design_parameters(self) -> dict:
        """Model parameters implied by the design values (Eq. 8 and Eq. 12)."""
        AO = self.kO * self.rO**2 / self.J2
        return {
            "AO": AO,
            "BO": (self.kO * self.xO1 * self.rO - self.TOf) / self.J2,
            "CO": self.CO,
            "DO": self.cb * self.rb**2 / self.J2,
            "EO": self.kb * self.rb**2 / self.J2,
            "AC": self.kC * self.rC * self.d / self.J1,
            "BC": self.J2 / self.J1,
            "CC": (self.TCf + self.kO * self.xO0 * self.rO) / self.J2,
            "DC": AO,
        }
