"""The effect catalogue: names, the operations each acts on, and per-capture shape draws.

Strength semantics: strength 0 is the reduced model's form; strength s scales each shape
parameter's departure from that form (an exponent n becomes 1 + s·(n1 - 1), an amplitude a
becomes s·a1, a rod frequency f becomes f1/s). Strength 1.0 is what a 252 kV-class mechanism in
service plausibly shows (REALISTIC says how much, measured on the nominal mechanism).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .mechanism import Effects

EFFECTS = ("orifice_buffer", "puffer_gas", "linkage_kinematics", "rod_elasticity",
           "stribeck_friction", "viscous_friction", "spring_nonlinearity", "sensor_nonlinearity",
           "contact_wipe", "cam_friction")
OUTSIDE = ("sensor_lag", "latch_ramp")

OPERATIONS = {
    "orifice_buffer": ("open",),
    "puffer_gas": ("open",),
    "linkage_kinematics": ("open", "close"),
    "rod_elasticity": ("open", "close"),
    "stribeck_friction": ("open", "close"),
    "viscous_friction": ("open", "close"),
    "spring_nonlinearity": ("open", "close"),
    "sensor_nonlinearity": ("open", "close"),
    "contact_wipe": ("close",),
    "cam_friction": ("close",),
    "sensor_lag": ("open", "close"),
    "latch_ramp": ("open", "close"),
}

REALISTIC = {
    # Figures: measured at strength 1 on the nominal mechanism, five shape draws each
    # (opening time = time to 20 % of the stroke, closing time = time to the latch).
    "orifice_buffer": "orifice law |v|^n with n = 1.3-1.6 (equal to cb·v at the 2.6 m/s design "
                      "speed), metering pin closing 15-35 % of the orifice area over the buffer "
                      "span, 5-15 mrad free travel: maximum travel changes by -1..+13 mrad, "
                      "opening time and peak speed unchanged",
    "puffer_gas": "SF6 puffer (0.7 MPa abs fill, 80 mm piston, volume ratio 1.6-3, polytropic "
                  "exponent 1.0-1.4, nozzle leak 15-50 1/s growing 8-fold once the nozzle clears "
                  "at 0.45-0.65 rad) on top of the linear damper: peak opening speed "
                  "-2..-5.5 %, maximum travel -2..-11 mrad",
    "linkage_kinematics": "transmission ratio varying by 3-6 % (first harmonic, 1.5-3 cycles per "
                          "rad) and 1-2 % (second, half the draws), free phases, end points kept: "
                          "travel differs by 2-8 mrad, peak speed by up to ±1.7 %",
    "rod_elasticity": "pull rod at 150-250 Hz with 3-10 % damping ratio, 30 % of the inertia on "
                      "the contact side, sensor on either side: 4-7 mrad ringing in openings, "
                      "4-22 mrad in closings (contact overshoot at the latch)",
    "stribeck_friction": "40-80 % of the paper's constant resistance torque becomes Coulomb "
                         "friction (sign of the speed) with static/kinetic ratio 1.5-2.0, "
                         "Stribeck speed 0.5-2.5 rad/s, shape exponent 1-2: opening time "
                         "+0.3..+0.9 %, the opening stops 1.5-6 mrad short and sticks instead of "
                         "rebounding (20-26 mrad after the peak); closings change by < 0.1 %",
    "viscous_friction": "viscous torque 0.8-1.6 N m s (3-7 s^-1 on J2), ±40 % along the "
                        "stroke: opening peak speed -2..-4 %, closing time +2..+3 %",
    "spring_nonlinearity": "progressive or degressive spring, force at full compression ±2-4 % "
                           "off the linear law (quadratic or cubic term): opening time ±2-3 %, "
                           "peak speed ±3-4 %; closing time ±0.5-4 %",
    "sensor_nonlinearity": "resistive transducer error of 4-10 mrad (0.1-0.3 % of its 180 deg "
                           "range), polynomial in travel or one-per-turn eccentricity, zero at "
                           "the closed position",
    "contact_wipe": "contacts touch 12-22 % of the stroke before closed; finger wedge peak "
                    "600-1000 N m over 10-30 mrad plus 200-400 N m wipe friction: closing time "
                    "+0.6..+0.9 %, travel after touch 2-4 mrad behind",
    "cam_friction": "cam-roller efficiency 0.97-0.985 at mid rise, loss varying ±60 % along the "
                    "rise: closing time +1.7..+3 %, peak closing speed -1.3..-2.4 %",
    "sensor_lag": "OUTSIDE the catalogue: first-order transducer/anti-alias lag of 100-250 us "
                  "(the travel reads speed·tau low while moving)",
    "latch_ramp": "OUTSIDE the catalogue: the latch releases the driving torque over a smooth "
                  "0.5-1.5 ms ramp instead of at once: opening time +4..+7 %, closing time "
                  "+1..+1.5 %",
}

# Design speed of the buffer [m/s]: the nominal engagement speed (32.6 rad/s at rb = 0.08 m);
# the orifice law equals the linear cb·v there, so the two buffers agree at the design point.
BUFFER_DESIGN_SPEED = 2.6
PUFFER_AREA = math.pi * 0.04 ** 2   # 80 mm puffer piston [m²]


def draw_shape(effect: str, operation: str, rng: np.random.Generator) -> dict:
    """Shape parameters of ``effect`` at strength 1, drawn within their physical bounds."""
    u = rng.uniform
    if effect == "orifice_buffer":
        return {"exponent": u(1.3, 1.6), "metering": u(0.15, 0.35), "free_travel_rad": u(0.005, 0.015)}
    if effect == "puffer_gas":
        return {"area_m2": PUFFER_AREA * u(0.85, 1.15), "kappa": u(1.0, 1.4),
                "volume_ratio": u(1.6, 3.0), "leak_per_s": u(15.0, 50.0),
                "nozzle_clear_rad": u(0.45, 0.65)}
    if effect == "linkage_kinematics":
        two = bool(rng.random() < 0.5)
        return {"a1": u(0.03, 0.06) * rng.choice([-1.0, 1.0]), "a2": u(0.01, 0.02) if two else 0.0,
                "harmonic_per_rad": u(1.5, 3.0), "phase1": u(0.0, 2 * math.pi),
                "phase2": u(0.0, 2 * math.pi)}
    if effect == "rod_elasticity":
        return {"frequency_hz": u(150.0, 250.0), "damping_ratio": u(0.03, 0.10),
                "sensor_side": str(rng.choice(["mechanism", "contact"]))}
    if effect == "stribeck_friction":
        return {"coulomb_share": u(0.4, 0.8), "static_excess": u(0.5, 1.0),
                "stribeck_speed_rad_s": u(0.5, 2.5), "shape": u(1.0, 2.0)}
    if effect == "viscous_friction":
        return {"viscous_nms": u(0.8, 1.6), "slope": u(-0.8, 0.8)}
    if effect == "spring_nonlinearity":
        which = "opening" if operation == "open" else str(rng.choice(["opening", "closing"]))
        return {"gamma": u(0.02, 0.04) * rng.choice([-1.0, 1.0]), "power": int(rng.choice([1, 2])),
                "spring": which}
    if effect == "sensor_nonlinearity":
        kind = str(rng.choice(["polynomial", "eccentric"]))
        amp = u(4e-3, 10e-3) * rng.choice([-1.0, 1.0])
        shape = u(0.0, 1.0) if kind == "polynomial" else u(0.0, 2 * math.pi)
        return {"kind": kind, "amplitude_rad": amp, "shape": shape}
    if effect == "contact_wipe":
        return {"touch_rad": u(0.78, 0.88), "width_rad": u(0.01, 0.03), "wedge_peak_nm": u(600.0, 1000.0),
                "friction_nm": u(200.0, 400.0)}
    if effect == "cam_friction":
        return {"loss": u(0.015, 0.03), "slope": u(-0.6, 0.6)}
    if effect == "sensor_lag":
        return {"tau_s": u(100e-6, 250e-6)}
    if effect == "latch_ramp":
        return {"ramp_s": u(0.5e-3, 1.5e-3)}
    raise ValueError(f"unknown effect {effect!r}; known: {', '.join(EFFECTS + OUTSIDE)}")


def apply_effect(eff: Effects, effect: str | None, strength: float, shape: dict) -> Effects:
    """Effects with ``effect`` switched on at ``strength`` using the strength-1 ``shape``."""
    s = float(strength)
    if effect is None or s == 0.0:
        return eff
    if effect == "orifice_buffer":
        return replace(eff, buffer_exponent=min(1.0 + s * (shape["exponent"] - 1.0), 2.0),
                       buffer_metering=min(s * shape["metering"], 0.7),
                       buffer_free=s * shape["free_travel_rad"], buffer_vref=BUFFER_DESIGN_SPEED)
    if effect == "puffer_gas":
        return replace(eff, gas_area=s * shape["area_m2"], gas_kappa=shape["kappa"],
                       gas_ratio=shape["volume_ratio"], gas_leak=shape["leak_per_s"],
                       gas_clear=shape["nozzle_clear_rad"])
    if effect == "linkage_kinematics":
        return replace(eff, link_a1=s * shape["a1"], link_a2=s * shape["a2"],
                       link_k=shape["harmonic_per_rad"], link_phi1=shape["phase1"],
                       link_phi2=shape["phase2"])
    if effect == "rod_elasticity":
        return replace(eff, rod_hz=shape["frequency_hz"] / s, rod_zeta=shape["damping_ratio"],
                       sensor_side=shape["sensor_side"])
    if effect == "stribeck_friction":
        return replace(eff, coulomb_share=min(s * shape["coulomb_share"], 1.0),
                       stribeck_rise=s * shape["static_excess"],
                       stribeck_speed=shape["stribeck_speed_rad_s"], stribeck_shape=shape["shape"])
    if effect == "viscous_friction":
        return replace(eff, viscous=s * shape["viscous_nms"], viscous_slope=shape["slope"])
    if effect == "spring_nonlinearity":
        return replace(eff, spring_gamma=s * shape["gamma"], spring_power=shape["power"],
                       spring_which=shape["spring"])
    if effect == "sensor_nonlinearity":
        return replace(eff, sensor_kind=shape["kind"], sensor_amp=s * shape["amplitude_rad"],
                       sensor_shape=shape["shape"])
    if effect == "contact_wipe":
        return replace(eff, wipe_touch=shape["touch_rad"], wipe_width=shape["width_rad"],
                       wipe_peak=s * shape["wedge_peak_nm"], wipe_friction=s * shape["friction_nm"])
    if effect == "cam_friction":
        return replace(eff, cam_loss=s * shape["loss"], cam_slope=shape["slope"])
    if effect == "sensor_lag":
        return replace(eff, sensor_lag=s * shape["tau_s"])
    if effect == "latch_ramp":
        return replace(eff, latch_ramp=s * shape["ramp_s"])
    raise ValueError(f"unknown effect {effect!r}; known: {', '.join(EFFECTS + OUTSIDE)}")
