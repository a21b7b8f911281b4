"""One physical unit of prototype D: its constants drawn about the design, the conditions of one
operation, and the parameter vector of the equations of motion (``dynamics``).

Design values are the reference breaker's (``config/breakers/reference-252kV.toml``, paper
Table 1 with xC0 = 0.37 m). The unit's constants are drawn within manufacturing tolerances
(``TOLERANCES``), the conditions per operation (``draw_conditions``); temperature acts through
``temperature_factors``.
"""

from __future__ import annotations

import math
import tomllib
from functools import lru_cache
from pathlib import Path

import numpy as np

from service.prototypes.d.dynamics import pack
from service.prototypes.d.effects import SCALES

BREAKER = Path(__file__).resolve().parents[3] / "config" / "breakers" / "reference-252kV.toml"
CONTACT_FRACTION = 0.6   # share of J2 that is the contact side (rod, contact, puffer cylinder)
G0_M_PER_RAD = 0.2       # 200 mm contact stroke over the 1 rad shaft stroke (252 kV class)

# Relative half-widths of the uniform manufacturing tolerances [-].
TOLERANCES = {
    "kC": 0.03, "xC0": 0.015, "d": 0.005, "rC": 0.005, "J1": 0.03, "theta1_start": 0.02,
    "kO": 0.03, "xO0": 0.02, "xO1": 0.015, "rO": 0.005, "J2": 0.03, "TCf": 0.05, "TOf": 0.05,
    "caec": 0.05, "raec": 0.005, "cb": 0.05, "kb": 0.05, "rb": 0.005, "alpha0": 0.02,
}
CAM_PHASE_RAD = 0.005     # cam keyed to the camshaft within ±5 mrad
SENSOR_GAIN = 0.01        # transducer gain within ±1 %
SENSOR_OFFSET_RAD = 2e-3  # and zero within ±2 mrad
VISCOSITY_ACTIVATION_K = 3540.0  # Andrade: MIL-PRF-5606-class oil, ν(−30 °C)/ν(20 °C) ≈ 12
DAMPING_VISCOSITY_EXPONENT = 0.4  # buffer: part laminar gap (∝ ν), part orifice (∝ ν⁰)
GREASE_FRICTION_PER_K = 0.002     # Coulomb friction +10 % at −30 °C, −4 % at +40 °C
SPRING_RATE_PER_K = -2.5e-4       # spring steel's shear modulus, dG/dT / G


@lru_cache(maxsize=1)
def design() -> dict:
    """The reference breaker's constants [SI] by name."""
    with open(BREAKER, "rb") as fh:
        cfg = tomllib.load(fh)
    out = {}
    for section in ("closing_spring", "opening_spring", "arc_chamber", "buffer"):
        out.update({k: float(v) for k, v in cfg[section].items()})
    out["cam_phase"] = 0.0
    out["sensor_gain"] = 1.0
    out["sensor_offset"] = 0.0
    return out


def draw_unit(rng: np.random.Generator) -> dict:
    """One unit: the design constants each scaled within its tolerance, the cam's keying, the
    transducer's gain and zero, the signs of its spring and sensor nonlinearities, and its
    noise character (see ``noise.draw_noise``)."""
    unit = dict(design())
    for name, tol in TOLERANCES.items():
        unit[name] *= 1.0 + rng.uniform(-tol, tol)
    unit["cam_phase"] = rng.uniform(-CAM_PHASE_RAD, CAM_PHASE_RAD)
    unit["sensor_gain"] = 1.0 + rng.uniform(-SENSOR_GAIN, SENSOR_GAIN)
    unit["sensor_offset"] = rng.uniform(-SENSOR_OFFSET_RAD, SENSOR_OFFSET_RAD)
    unit["spring_sign"] = float(rng.choice([-1.0, 1.0]))
    unit["sensor_sign"] = float(rng.choice([-1.0, 1.0]))
    return unit


def draw_conditions(rng: np.random.Generator, pretrigger_s: float = 0.020) -> dict:
    """One operation's conditions: ambient temperature [°C] uniform −30…+40, the latch release
    time [s from the first sample] (pre-trigger ± 0.5 ms jitter) and the mechanism's linear
    (arc-chamber) damping, which varies ±3 % (sd) from operation to operation."""
    return {"temperature_C": float(rng.uniform(-30.0, 40.0)),
            "trigger_delay_s": float(pretrigger_s + rng.uniform(-0.5e-3, 0.5e-3)),
            "damping_factor": float(1.0 + 0.03 * rng.standard_normal())}


def temperature_factors(temperature_C: float) -> dict:
    """Multipliers at temperature_C [°C] relative to 20 °C: ``damping`` (buffer oil and grease
    viscous friction), ``friction`` (grease Coulomb friction) and ``stiffness`` (springs)."""
    visc = math.exp(VISCOSITY_ACTIVATION_K * (1 / (temperature_C + 273.15) - 1 / 293.15))
    return {"damping": visc ** DAMPING_VISCOSITY_EXPONENT,
            "friction": 1.0 + GREASE_FRICTION_PER_K * (20.0 - temperature_C),
            "stiffness": 1.0 + SPRING_RATE_PER_K * (temperature_C - 20.0)}


def physical(unit: dict, conditions: dict) -> dict:
    """The unit's constants under these conditions [SI]."""
    f = temperature_factors(conditions["temperature_C"])
    out = dict(unit)
    out["kO"] = unit["kO"] * f["stiffness"]
    out["kC"] = unit["kC"] * f["stiffness"]
    out["cb"] = unit["cb"] * f["damping"]
    out["TOf"] = unit["TOf"] * f["friction"]
    out["TCf"] = unit["TCf"] * f["friction"]
    out["caec"] = unit["caec"] * conditions["damping_factor"]
    out["viscous_factor"] = f["damping"]
    return out


def reduced_truth(operation: str, c: dict) -> dict:
    """The paper's reduced-model parameters these constants imply (Eqs. 8 and 12)."""
    AO = c["kO"] * c["rO"] ** 2 / c["J2"]
    if operation == "open":
        return {"AO": AO, "BO": (c["kO"] * c["xO1"] * c["rO"] - c["TOf"]) / c["J2"],
                "CO": c["caec"] * c["raec"] ** 2 / c["J2"], "DO": c["cb"] * c["rb"] ** 2 / c["J2"],
                "EO": c["kb"] * c["rb"] ** 2 / c["J2"]}
    return {"AC": c["kC"] * c["rC"] * c["d"] / c["J1"], "BC": c["J2"] / c["J1"],
            "CC": (c["TCf"] + c["kO"] * c["xO0"] * c["rO"]) / c["J2"], "DC": AO,
            "xC0_m": c["xC0"], "rC_m": c["rC"], "d_m": c["d"],
            "theta1_start_rad": c["theta1_start"], "cam_phase_rad": c["cam_phase"]}


def parameter_vector(operation: str, c: dict, effects: dict, v_ref: float = 1.0) -> np.ndarray:
    """The dynamics' parameter vector for ``operation`` of constants c [SI] with ``effects``
    ({name: strength}); v_ref [m/s] is the buffer speed at which the orifice law matches the
    linear damping (``design_buffer_speed``)."""
    s = {name: float(effects.get(name, 0.0)) for name in SCALES}
    m_c = CONTACT_FRACTION * c["J2"] / G0_M_PER_RAD ** 2
    sc = SCALES
    v = {"J_s": (1 - CONTACT_FRACTION) * c["J2"], "m_c": m_c, "G0": G0_M_PER_RAD,
         "s_link": s["linkage_kinematics"] * sc["linkage_kinematics"]["s_link"],
         "stroke": 1.0, "cam_phase": c["cam_phase"]}
    tf = c["TOf"] if operation == "open" else c["TCf"]
    v["T_fric"] = tf
    if s["stribeck_friction"]:
        v["dT_stribeck"] = s["stribeck_friction"] * sc["stribeck_friction"]["excess_fraction"] * tf
        v["w_stribeck"] = sc["stribeck_friction"]["w_s_rad_s"]
    v["c_visc"] = s["viscous_friction"] * sc["viscous_friction"]["c_Nms"] * c["viscous_factor"]
    k_rod = k_pin = math.inf
    zeta = 0.0
    if s["rod_elasticity"]:
        k_rod = m_c * (2 * math.pi * sc["rod_elasticity"]["f_Hz"]) ** 2 / s["rod_elasticity"]
        zeta = sc["rod_elasticity"]["zeta"]
    if s["pin_backlash"]:
        k_pin = m_c * (2 * math.pi * sc["pin_backlash"]["f_contact_Hz"]) ** 2
        v["gap"] = s["pin_backlash"] * sc["pin_backlash"]["gap_m"]
        zeta = max(zeta, sc["pin_backlash"]["zeta"])
    if math.isfinite(k_rod) or math.isfinite(k_pin):
        v["k_cpl"] = 1.0 / (1.0 / k_rod + 1.0 / k_pin)
        v["c_cpl"] = 2 * zeta * math.sqrt(v["k_cpl"] * m_c)
    v["tau_latch"] = s["latch_ramp"] * sc["latch_ramp"]["tau_s"]
    e = s["spring_nonlinearity"] * sc["spring_nonlinearity"]["e"] * c["spring_sign"]
    v["e_spring"] = e
    if operation == "open":
        v.update(k_spring=c["kO"], x_lo=c["xO0"], x_hi=c["xO1"], xO1=c["xO1"], rO=c["rO"],
                 c_aec_x=c["caec"] * c["raec"] ** 2 / G0_M_PER_RAD ** 2, alpha0=c["alpha0"],
                 rb=c["rb"], cb=c["cb"], kb=c["kb"], v_ref=v_ref,
                 s_orifice=s["orifice_buffer"] * sc["orifice_buffer"]["exponent_excess"])
        if s["puffer_gas"]:
            pg = sc["puffer_gas"]
            v.update(A_p=s["puffer_gas"] * pg["A_p_m2"], A_n=s["puffer_gas"] * pg["A_n_m2"],
                     p0=pg["p0_Pa"], gamma=pg["gamma"], rho0=pg["rho0_kg_m3"], L0=pg["L0_m"],
                     Cd=pg["Cd"])
        else:
            v["p0"] = 1.0  # inert (A_p = 0); keeps the pressure state finite
    else:
        # the closing spring's working range: θ1 from 0 to π
        v.update(k_spring=c["kC"], x_lo=c["xC0"] - 2 * c["rC"], x_hi=c["xC0"], xC0=c["xC0"],
                 rC=c["rC"], d=c["d"], kO=c["kO"], xO0=c["xO0"], rO=c["rO"], J1=c["J1"],
                 c_cam=s["cam_friction"] * sc["cam_friction"]["mu_eff"])
        if s["contact_wipe"]:
            cw = sc["contact_wipe"]
            v.update(F_wipe=s["contact_wipe"] * cw["F_n_N"], mu_wipe=cw["mu"],
                     tan_chamfer=cw["tan_chamfer"], l_chamfer=cw["l_chamfer_m"],
                     theta2_touch=cw["theta2_touch"])
    return pack(v)
