"""Prototype A's effects: which of the catalogue's effects (service.mechanics.effects) it switches
on, and how strongly.

Each strength is a dimensionless fraction (0 = off, the reduced model). The names and the
equations are the catalogue's; this module gives A's realistic strengths for a 252 kV-class
mechanism (used by the studies and the demo histories) and the largest it simulates.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np

from service.mechanics.effects.catalogue import (EFFECT_NAMES, FAMILY, LOCALITY, OPERATIONS, REGIONS, SHAPES,
                                                SIGNED, effect_vector, shape_bounds, shape_defaults)

__all__ = ["EFFECT_NAMES", "FAMILY", "LOCALITY", "OPERATIONS", "REGIONS", "SHAPES", "SIGNED", "effect_vector",
           "shape_bounds", "shape_defaults", "REALISTIC", "UPPER", "Effects", "check_operation"]

# Realistic strengths for the reference breaker [-]: each leaves a gap of a few noise floors
# (0.0015 rad) on the reduced-model fit, like the 8-13 mrad the paper reports against ADAMS.
REALISTIC = {
    "linkage_kinematics": 0.25,
    "orifice_buffer": 0.6,
    "puffer_gas": 0.08,
    "rod_elasticity": 1.0,
    "stribeck_friction": 0.3,
    "viscous_friction": 0.1,
    "spring_nonlinearity": 0.3,
    "sensor_nonlinearity": 0.01,
    "cam_friction": 0.1,
    "contact_wipe": 0.3,
}

# Largest strength the fitters may use [-] (physics stays meaningful below it).
UPPER = {
    "linkage_kinematics": 0.9, "orifice_buffer": 5.0, "puffer_gas": 1.0, "rod_elasticity": 6.0,
    "stribeck_friction": 0.9, "viscous_friction": 3.0, "spring_nonlinearity": 3.0,
    "sensor_nonlinearity": 0.1, "cam_friction": 0.6, "contact_wipe": 3.0,
}


@dataclass(frozen=True)
class Effects:
    """Strengths of the prototype's physical effects [-]; all 0 is the reduced model.

    Attributes
    ----------
    linkage_kinematics : float
        λ, relative drop of the equivalent inertia and transmission ratio at the stroke ends.
    orifice_buffer : float
        γ, orifice (v·|v|) buffer force at 20 rad/s as a fraction of the linear DO·v force.
    puffer_gas : float
        π_g, puffer-gas pressure force at full stroke as a fraction of BO.
    rod_elasticity : float
        ε = (150 Hz / f_rod)², compliance of the insulating pull rod.
    stribeck_friction : float
        σ, breakaway friction above sliding, as a fraction of the static drive.
    viscous_friction : float
        ν, bearing viscous friction as a fraction of CO.
    spring_nonlinearity : float
        β, progressive stiffness: k(x) = k·(1 + β·x/x_ref).
    sensor_nonlinearity : float
        ε_s, bow of the angle sensor at mid-stroke as a fraction of the stroke.
    cam_friction : float
        1 − η, power lost in the cam–roller transmission.
    contact_wipe : float
        w, contact-finger load at the end of the wipe as a fraction of CC.
    """

    linkage_kinematics: float = 0.0
    orifice_buffer: float = 0.0
    puffer_gas: float = 0.0
    rod_elasticity: float = 0.0
    stribeck_friction: float = 0.0
    viscous_friction: float = 0.0
    spring_nonlinearity: float = 0.0
    sensor_nonlinearity: float = 0.0
    cam_friction: float = 0.0
    contact_wipe: float = 0.0

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"effect strength {f.name} must be a finite number >= 0, got {v}")
        if self.cam_friction >= 1:
            raise ValueError("cam_friction is 1 - η and must be below 1 (η > 0)")
        if self.linkage_kinematics >= 1:
            raise ValueError("linkage_kinematics must be below 1 (the inertia stays positive)")
        if self.stribeck_friction >= 1:
            raise ValueError("stribeck_friction must be below 1 (the breakaway friction must not "
                             "hold the mechanism)")

    @classmethod
    def only(cls, name: str, strength: float) -> "Effects":
        """One effect at ``strength``, all others off."""
        if name not in EFFECT_NAMES:
            raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")
        return cls(**{name: float(strength)})

    def as_array(self) -> np.ndarray:
        return np.array([getattr(self, n) for n in EFFECT_NAMES], dtype=float)

    def active(self) -> tuple:
        return tuple(n for n in EFFECT_NAMES if getattr(self, n) > 0)

    def to_dict(self) -> dict:
        return asdict(self)


def check_operation(effects: Effects, operation: str) -> None:
    """Refuse an effect that has no meaning for ``operation``."""
    if operation not in ("open", "close"):
        raise ValueError(f"operation must be 'open' or 'close', got {operation!r}")
    wrong = [n for n in effects.active() if operation not in OPERATIONS[n]]
    if wrong:
        raise ValueError(f"effect(s) {', '.join(wrong)} do not act on a{'n' if operation == 'open' else ''} "
                         f"{'opening' if operation == 'open' else 'closing'}")
