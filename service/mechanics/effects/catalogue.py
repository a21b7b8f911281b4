"""The catalogue of physical effects the reduced models (Eqs. 7 and 11) leave out.

Production code's one description of them: the names, the operations each acts on, the phases
where it acts, each family's shape parameters with their physical bounds, and the largest
physical strength. The equations are one module per effect in this package; ``integrator``
integrates any set of them (compiled fixed-step RK4). How strong an effect typically is on a
given breaker is a fact about that breaker: its breaker file's ``[effects]`` table
(``REFERENCE_STRENGTHS`` are the 252 kV reference breaker's, the default when a file has none).
"""

from __future__ import annotations

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

# Where each effect acts, in the diagnosis's phase names (service.diagnosis.phases).
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

# Largest strength a fit may give a family [-]: its physical limit, so that smooth whole-stroke families cannot absorb
# any gap: a sensor's linearity error ≤ 2 % of full scale, a linkage's inertia variation ≤ 50 %.
PHYSICAL_UPPER = {
    "linkage_kinematics": 0.5, "orifice_buffer": 5.0, "puffer_gas": 1.0, "rod_elasticity": 6.0,
    "stribeck_friction": 0.9, "viscous_friction": 3.0, "spring_nonlinearity": 1.0,
    "sensor_nonlinearity": 0.02, "cam_friction": 0.3, "contact_wipe": 3.0,
}

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

# Typical strengths on the reference 252 kV breaker [-] (config/breakers/reference-252kV.toml):
# each leaves a gap of a few noise floors (0.0015 rad) on the reduced-model fit, like the
# 8-13 mrad the paper reports against ADAMS. Scales of the fits and the "absorbed" check.
REFERENCE_STRENGTHS = {
    "linkage_kinematics": 0.25, "orifice_buffer": 0.6, "puffer_gas": 0.08, "rod_elasticity": 1.0,
    "stribeck_friction": 0.3, "viscous_friction": 0.1, "spring_nonlinearity": 0.3,
    "sensor_nonlinearity": 0.01, "cam_friction": 0.1, "contact_wipe": 0.3,
}

# The names the card and the CLI show (the identifier goes in a tooltip / the JSON).
NAMES_IN_WORDS = {
    "linkage_kinematics": "linkage kinematics (varying transmission ratio)",
    "orifice_buffer": "orifice buffer (damping ∝ speed²)",
    "puffer_gas": "puffer gas compression",
    "rod_elasticity": "pull-rod elasticity",
    "stribeck_friction": "breakaway (Stribeck) friction",
    "viscous_friction": "viscous bearing friction",
    "spring_nonlinearity": "spring nonlinearity",
    "sensor_nonlinearity": "travel-sensor nonlinearity",
    "cam_friction": "cam-roller friction",
    "contact_wipe": "contact wipe load",
    "none": "no unmodelled effect",
    "outside_catalogue": "outside the catalogue",
    "unattributed": "not attributed (how often such an answer is wrong)",
}


def in_words(answer: str) -> str:
    """An answer (effects joined by "+", "none", "outside_catalogue") in words."""
    return " + ".join(NAMES_IN_WORDS.get(a, a.replace("_", " ")) for a in answer.split("+"))
