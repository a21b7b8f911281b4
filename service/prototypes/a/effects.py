"""The catalogue of physical effects the reduced models leave out, and their strengths.

Each strength is a dimensionless fraction (0 = off, the reduced model). The equations live in one
module per effect; this module only names them, says where each acts, and gives a realistic
strength for a 252 kV-class mechanism (used by the blind study and the demo histories).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np

EFFECT_NAMES = (
    "linkage_kinematics", "orifice_buffer", "puffer_gas", "rod_elasticity", "stribeck_friction",
    "viscous_friction", "spring_nonlinearity", "sensor_nonlinearity", "cam_friction", "contact_wipe",
)

# Which operations each effect can act on.
OPERATIONS = {
    "linkage_kinematics": ("open", "close"),
    "orifice_buffer": ("open",),
    "puffer_gas": ("open",),
    "rod_elasticity": ("open", "close"),
    "stribeck_friction": ("open", "close"),
    "viscous_friction": ("open", "close"),
    "spring_nonlinearity": ("open", "close"),
    "sensor_nonlinearity": ("open", "close"),
    "cam_friction": ("close",),
    "contact_wipe": ("close",),
}

# Where each effect acts, in the diagnosis's phase names (see service.diagnosis.phases).
REGIONS = {
    "open": {
        "linkage_kinematics": ("acceleration", "buffer_engagement", "buffer_stroke", "approach"),
        "orifice_buffer": ("buffer_engagement", "buffer_stroke", "approach"),
        "puffer_gas": ("buffer_engagement", "buffer_stroke", "approach"),
        "rod_elasticity": ("acceleration", "buffer_engagement"),
        "stribeck_friction": ("acceleration",),
        "viscous_friction": ("acceleration", "buffer_engagement", "buffer_stroke", "approach"),
        "spring_nonlinearity": ("acceleration", "buffer_engagement", "buffer_stroke", "approach"),
        "sensor_nonlinearity": ("acceleration", "buffer_engagement", "buffer_stroke", "approach"),
    },
    "close": {
        "linkage_kinematics": ("cam_rise", "contact_touch", "end"),
        "rod_elasticity": ("cam_rise", "contact_touch", "end"),
        "stribeck_friction": ("free_run",),
        "viscous_friction": ("cam_rise", "contact_touch", "end"),
        "spring_nonlinearity": ("free_run", "cam_rise", "contact_touch", "end"),
        "sensor_nonlinearity": ("free_run", "cam_rise", "contact_touch", "end"),
        "cam_friction": ("cam_rise", "contact_touch", "end"),
        "contact_wipe": ("contact_touch", "end"),
    },
}

# Phase-local effects act in one part of the stroke (a buffer, the contacts, the start of motion,
# the puffer's end of stroke); whole-stroke effects change the curve everywhere and, being smooth,
# can mimic many gaps. Between equally good explanations the local one acting where the gap is wins.
LOCALITY = {
    "orifice_buffer": "local", "puffer_gas": "local", "contact_wipe": "local",
    "stribeck_friction": "local", "rod_elasticity": "local", "cam_friction": "whole_stroke",
    "linkage_kinematics": "whole_stroke", "viscous_friction": "whole_stroke",
    "spring_nonlinearity": "whole_stroke", "sensor_nonlinearity": "whole_stroke",
}

# Mechanism families: rivals within the margin that share one are reported by its name.
FAMILY = {
    "stribeck_friction": "friction", "viscous_friction": "friction", "cam_friction": "friction",
    "orifice_buffer": "end_of_stroke_damping", "puffer_gas": "end_of_stroke_damping",
    "linkage_kinematics": "kinematics", "sensor_nonlinearity": "kinematics",
    "rod_elasticity": "compliance", "spring_nonlinearity": "spring", "contact_wipe": "contacts",
}

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


# Shape parameters of each effect's family (issue 11): (name, prototype default, lower, upper).
# The prototype uses the defaults (its own equations); the diagnosis fits them within the bounds,
# which are the physically plausible forms of the mechanism. Units in each effect's module.
SHAPES = {
    "linkage_kinematics": (("phase_rad", 0.0, -0.6, 0.6), ("second_harmonic", 0.0, 0.0, 1.0)),
    "orifice_buffer": (("exponent", 2.0, 1.0, 2.0), ("metering", 0.5, 0.0, 0.7),
                       ("free_travel_rad", 0.0, 0.0, 0.03)),
    "puffer_gas": (("polytropic", 1.4, 1.0, 1.4), ("volume_ratio", 1.6, 1.2, 3.0),
                   ("leak_rate_per_s", 0.0, 0.0, 150.0)),
    "rod_elasticity": (("damping_ratio", 0.05, 0.02, 0.3), ("sensor_side", 0.0, 0.0, 1.0)),
    "stribeck_friction": (("stribeck_speed_rad_s", 2.0, 0.3, 5.0), ("stribeck_exponent", 2.0, 1.0, 2.0)),
    "viscous_friction": (("slope", 0.0, -0.8, 0.8),),
    "spring_nonlinearity": (("power", 2.0, 2.0, 3.0), ("opening_spring_share", 0.0, 0.0, 1.0)),
    "sensor_nonlinearity": (("power", 2.0, 2.0, 3.0), ("end_calibration", 1.0, -1.0, 2.0)),
    "cam_friction": (("rise_slope", 0.0, -1.0, 1.0),),
    "contact_wipe": (("touch_fraction", 0.7, 0.5, 0.9), ("spring_share", 0.5, 0.0, 1.0)),
}
N_SHAPES = 3  # slots per effect in the compiled vector

# Largest strength a diagnosis fit may give a family [-]: realistic physical limits (tighter than
# UPPER, which bounds the prototype itself), so that smooth whole-stroke families cannot absorb
# any gap: a sensor's linearity error ≤ 2 % of full scale, a linkage's inertia variation ≤ 50 %.
FIT_UPPER = {**UPPER, "sensor_nonlinearity": 0.02, "linkage_kinematics": 0.5, "cam_friction": 0.3,
             "spring_nonlinearity": 1.0}

# Effects whose family allows a negative strength (degressive spring, sensor reading high).
SIGNED = ("spring_nonlinearity", "sensor_nonlinearity")


def shape_defaults(name: str) -> np.ndarray:
    return np.array([s[1] for s in SHAPES[name]], float)


def shape_bounds(name: str):
    return (np.array([s[2] for s in SHAPES[name]], float), np.array([s[3] for s in SHAPES[name]], float))


def effect_vector(strengths, shapes=None) -> np.ndarray:
    """The compiled dynamics' vector: 10 strengths, then N_SHAPES slots per effect (defaults
    unless ``shapes`` = {effect: sequence} overrides them)."""
    v = np.zeros(len(EFFECT_NAMES) * (1 + N_SHAPES))
    v[: len(EFFECT_NAMES)] = strengths
    for k, name in enumerate(EFFECT_NAMES):
        sh = shape_defaults(name) if not shapes or name not in shapes else np.asarray(shapes[name], float)
        i0 = len(EFFECT_NAMES) + N_SHAPES * k
        v[i0: i0 + sh.size] = sh
    return v


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
