"""Prototype D's effects: their names, the operations they act on, and each one's strength scale.

Every effect has a dimensionless strength s (0 = off); s = 1 is the typical field magnitude
given in ``SCALES`` with its source or derivation (docs/prototype-d.md has the laws).
"""

from __future__ import annotations

import math

EFFECTS = (
    "linkage_kinematics", "orifice_buffer", "puffer_gas", "rod_elasticity", "stribeck_friction",
    "viscous_friction", "spring_nonlinearity", "sensor_nonlinearity", "cam_friction",
    "contact_wipe",
)
OUTSIDE = ("sensor_lag", "latch_ramp", "pin_backlash")
BOTH = ("open", "close")
OPERATIONS = {
    "linkage_kinematics": BOTH, "orifice_buffer": ("open",), "puffer_gas": ("open",),
    "rod_elasticity": BOTH, "stribeck_friction": BOTH, "viscous_friction": BOTH,
    "spring_nonlinearity": BOTH, "sensor_nonlinearity": BOTH, "cam_friction": ("close",),
    "contact_wipe": ("close",), "sensor_lag": BOTH, "latch_ramp": BOTH, "pin_backlash": BOTH,
}

# s = 1 of each effect. Sources and derivations: docs/prototype-d.md, section "The effects".
SCALES = {
    # crank swinging ±0.5 rad about its perpendicular: G varies as cos, −12 % at the stroke ends
    "linkage_kinematics": {"s_link": 1.0},
    # damping force exponent 1 + s: s = 1 is the turbulent orifice law Δp ∝ Q²
    "orifice_buffer": {"exponent_excess": 1.0},
    # 50 mm bore, compression ratio 3, SF6 at 0.6 MPa abs, 14 mm equivalent leak (arcing-contact
    # gap and nozzle): no-load overpressure peaks near 0.25 MPa late in the stroke
    "puffer_gas": {"A_p_m2": 2.0e-3, "A_n_m2": 1.5e-4, "p0_Pa": 0.6e6, "gamma": 1.1,
                   "rho0_kg_m3": 36.0, "L0_m": 0.30, "Cd": 0.6},
    # pull-rod mode of the contact mass at 200 Hz; compliance ∝ s, so f = 200 Hz / √s
    "rod_elasticity": {"f_Hz": 200.0, "zeta": 0.05},
    # static/kinetic friction 1.6 (greased steel, boundary lubrication); Stribeck speed 2 rad/s
    "stribeck_friction": {"excess_fraction": 0.6, "w_s_rad_s": 2.0},
    # greased pins, bearings and seals: at an opening's peak speed (~30 rad/s) 5 % of TOf
    "viscous_friction": {"c_Nms": 1.0},
    # coil contact: local rate at the compressed end ±30 % of nominal (e = ±0.15)
    "spring_nonlinearity": {"e": 0.15},
    # independent linearity of a resistive transducer ±0.5 % of the 1 rad stroke: 5 mrad bow
    "sensor_nonlinearity": {"bow_rad": 5.0e-3},
    # effective friction coefficient of a roller follower referred to the contact (rolling
    # resistance + needle-bearing friction, 0.005–0.03), cam and roller arms taken equal
    "cam_friction": {"mu_eff": 0.02},
    # main and arcing fingers ~2.5 kN normal in all, silver greased μ 0.2, 15° chamfer over
    # 5 mm; touch at 75 % of the stroke (a 50 mm wipe of 200 mm)
    "contact_wipe": {"F_n_N": 2500.0, "mu": 0.2, "tan_chamfer": 0.27, "l_chamfer_m": 5e-3,
                     "theta2_touch": 0.75},
    # transducer first-order lag
    "sensor_lag": {"tau_s": 0.5e-3},
    # latch release ramp
    "latch_ramp": {"tau_s": 1.5e-3},
    # worn pins in series: 1 mm total free play at the contact; pin contact stiffness as a
    # 1.5 kHz mode of the contact mass
    "pin_backlash": {"gap_m": 1.0e-3, "f_contact_Hz": 1500.0, "zeta": 0.1},
}


def check_effects(effects: dict, operation: str) -> None:
    """Raise ValueError unless every effect is known, acts on ``operation`` and has s ≥ 0."""
    if operation not in BOTH:
        raise ValueError(f"operation must be 'open' or 'close', got {operation!r}")
    for name, s in effects.items():
        if name not in OPERATIONS:
            raise ValueError(f"unknown effect {name!r}; prototype D knows "
                             f"{', '.join(EFFECTS + OUTSIDE)}")
        if operation not in OPERATIONS[name]:
            raise ValueError(f"effect {name!r} acts on {' and '.join(OPERATIONS[name])}, "
                             f"not on {operation}")
        if not (isinstance(s, (int, float)) and math.isfinite(s) and s >= 0):
            raise ValueError(f"strength of {name!r} must be a finite number ≥ 0, got {s!r}")
