"""Prototype E: constants, the unit, the conditions and the cam of the reference breaker.

Mechanism family of E (see docs/prototype-e.md): the output shaft drives the moving
contact through a crank-slider *four-bar* (crank, coupler, contact-rod slider) and a
pull/insulating rod; the opening is stopped by an oil dashpot buffer acting on the output
shaft; the travel is read by a *linear* transducer driven by a slotted lever on the
output shaft.  With every effect off and the design unit, the linkage has the constant
ratio ``raec`` [m/rad], the rod is rigid, the buffer is linear, friction is the paper's
constant torque and E reduces exactly to Yan et al. 2026, Eq. 7 (closing) and Eq. 11
(opening).

All quantities SI (m, kg, s, N, rad, K) unless the name says otherwise.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field, asdict
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

HERE = Path(__file__).resolve().parent

# --------------------------------------------------------------------------------------
# Reference breaker (reference-252kV.toml = Table 1 of the paper, xC0 = 0.37 m)
# --------------------------------------------------------------------------------------
REFERENCE = dict(
    kC=90e3, xC0=0.37, d=0.29, rC=0.086, J1=0.095, theta1_start=0.20,
    kO=130e3, xO0=0.09, xO1=0.17, rO=0.08, J2=0.243, TCf=1600.0, TOf=600.0,
    caec=1000.0, raec=0.15, cb=1500.0, kb=150e3, rb=0.08, alpha0=0.698,
)

# --------------------------------------------------------------------------------------
# E's own structure (design values; not in the paper)
# --------------------------------------------------------------------------------------
#: moving mass on the contact side of the linkage [kg]: moving contact, puffer cylinder,
#: nozzle and the insulating pull rod of a 252 kV puffer interrupter (typ. 4-7 kg).
M_CONTACT = 5.0
# The output-shaft side's inertia J_shaft is J2 minus the contact mass referred through
# the design linkage ratio raec (J2 = J_shaft + M_CONTACT * raec^2 holds exactly).

#: crank-slider four-bar between the output shaft and the contact rod (linkage_kinematics)
LINK_CRANK = 0.16       # crank radius on the output shaft [m]
LINK_COUPLER = 0.35     # coupler length [m]
LINK_OFFSET = 0.08      # slider-axis offset from the shaft axis [m]
LINK_PHI0 = -0.45       # crank angle from the slider normal at the closed position [rad]
#: over the 1-rad stroke this four-bar's ratio runs 0.85 -> 1.05 -> 0.97 of its mean,
#: i.e. about +-10 %, the usual spread of breaker linkages (designed for a high contact
#: speed at separation); s = 1 is this linkage.

# temperature: Arrhenius law of the buffer oil's kinematic viscosity.  A VG10-15
# aviation hydraulic oil (MIL-H-5606 class: 13.2 cSt at 40 C, ~37 cSt at 0 C) gives
# B ~ 2200 K between 0 and 40 C.
T_REF_C = 20.0
OIL_B_K = 2200.0
#: laminar (viscosity-proportional) share of the linear buffer's damping: annular
#: piston clearance; the metering holes carry the rest (viscosity-independent).
BUFFER_LAMINAR_SHARE = 0.25
#: grease in the linkage pins and shaft bearings: Coulomb friction rises ~0.3 %/K in
#: the cold (lithium grease, -10..40 C; consistent with 10-20 % spread of TOf reported
#: for outdoor mechanisms between summer and winter).
FRICTION_TEMP_COEFF = -0.003
#: share of TCf that is friction (the rest is pneumatic/contact resistance, Sec. 2.2)
TCF_FRICTION_SHARE = 0.6
GREASE_B_K = 2000.0     # viscous-friction grease viscosity, Arrhenius [K]

# --------------------------------------------------------------------------------------
# effect scales (s = 1): each justified in docs/prototype-e.md
# --------------------------------------------------------------------------------------
SCALE = dict(
    # orifice_buffer: damper exponent n = 1 + tanh(s) (n = 1.76 at s = 1, the mixed
    # laminar/turbulent regime of real metering orifices), force matched to the linear
    # law at the design engagement speed of the buffer piston.
    # puffer_gas: puffer bore 95 mm, dead length 0.20 m, SF6 0.6 MPa abs at 20 C,
    # nozzle throat Cd*A = 4.0e-4 m^2 -> peak over-pressure ~0.13 MPa at ~70 % of the stroke.
    puffer_area=7.1e-3, puffer_length=0.20, sf6_fill_pa=0.6e6, sf6_density=36.0,
    sf6_gamma=1.1, nozzle_cda=4.0e-4, gas_dp_reg=2.0e3,
    # rod_elasticity: GFRP pull rod 40 mm, E = 25 GPa, 1.5 m, with its end fittings in
    # series: 8e6 N/m at s = 1 (compliance proportional to s); 3 % damping ratio.
    rod_stiffness=8.0e6, rod_zeta=0.03,
    # stribeck_friction: breakaway/sliding = 1.4 (greased steel/bronze pins, mu_s 0.14
    # vs mu_k 0.10); Stribeck speed 1 rad/s (0.03 m/s at a 30 mm bearing radius).
    # In the closing it also acts on the camshaft bearings: closing-spring load ~33 kN,
    # mu_k 0.1 at a 30 mm journal radius -> ~100 N m sliding friction (inside AC).
    stribeck_ratio=1.4, stribeck_speed=1.0, stribeck_eps=0.05, cam_bearing_friction=100.0,
    # viscous_friction: 1.0 N m s/rad at 20 C (bearings and the puffer-rod seals), ~60 N m
    # at the opening's peak speed (10 % of TOf).
    viscous_coeff=1.0,
    # spring_nonlinearity: rate changes +-10 % from the middle to the ends of the
    # working deflection (end-coil contact / pitch tolerance of long helical springs).
    spring_rate_slope=0.10,
    # sensor_nonlinearity: integral nonlinearity 0.15 % of full scale (conductive-plastic
    # potentiometer, datasheets 0.05-0.2 %, worn track in the field more).
    sensor_inl=0.0015,
    # cam_friction: effective coefficient 0.04 at the cam-roller contact (free rolling
    # roller ~0.005; stiff/dry roller bearing with partial sliding up to 0.1), s = 1 at 0.015 (the reference breaker has a thin closing-energy margin: 0.04 at s = 1.5 stalls a cold unit).
    cam_mu=0.015, cam_gate=0.05,
    # contact_wipe: main fingers 3000 N total normal load, arcing tulip 600 N, mu 0.2
    # (Ag-Ag), entry chamfer 30 deg; main contact touches at 22 mm from closed with
    # 2 mm finger lift, arcing contact at 45 mm with 1.5 mm lift.
    main_normal=3000.0, main_touch=0.022, main_lift=0.002,
    arc_normal=600.0, arc_touch=0.045, arc_lift=0.0015,
    wipe_mu=0.2, wipe_chamfer_deg=30.0, wipe_eps=0.01,
    # spring_surge (outside): distributed mass of the opening spring 8 kg at s = 1
    # (130 kN/m, ~1.9 kJ at full compression, ~150 J/kg); first surge mode
    # 0.5 sqrt(k/m) = 64 Hz; 2 % internal damping.
    spring_mass=8.0, spring_zeta=0.02,
)

# --------------------------------------------------------------------------------------
# travel sensor: linear transducer on a slotted lever of the output shaft
# --------------------------------------------------------------------------------------
LEVER_R = 0.100          # lever radius [m] (nominal)
LEVER_BETA = -0.50       # lever angle at the closed position from the transducer normal [rad]
TRANSDUCER_FS = 0.150    # transducer stroke [m]
TRANSDUCER_OFFSET = 0.020  # transducer position at the closed position [m]
ADC_BITS = 16

SAMPLE_RATE = 128_000.0
N_OPEN = 20_480
N_CLOSE = 32_000
PRETRIGGER_S = 0.020
SUBSTEPS = 2

EFFECT_INDEX = {
    "linkage_kinematics": 0, "orifice_buffer": 1, "puffer_gas": 2, "rod_elasticity": 3,
    "stribeck_friction": 4, "viscous_friction": 5, "spring_nonlinearity": 6,
    "sensor_nonlinearity": 7, "cam_friction": 8, "contact_wipe": 9, "spring_surge": 10,
}
N_EFFECTS = len(EFFECT_INDEX)


# --------------------------------------------------------------------------------------
# cam
# --------------------------------------------------------------------------------------
def load_cam(path: Path | None = None):
    """Cubic interpolating spline of the cam profile theta2 = h(theta1) (closing
    coordinate), returned as (breaks, coefficients[4, n]) of its piecewise polynomial;
    h' and h'' are continuous.  Outside the table h is held at its end values."""
    path = path or HERE / "cam-profile.csv"
    with open(path, newline="") as fh:
        rows = [r for r in csv.reader(fh)][1:]
    x = np.array([float(r[0]) for r in rows])
    y = np.array([float(r[1]) for r in rows])
    cs = CubicSpline(x, y, bc_type="clamped")  # h' = 0 at both ends (dwells)
    return np.ascontiguousarray(cs.x, dtype=np.float64), np.ascontiguousarray(cs.c, dtype=np.float64)


CAM_BREAKS, CAM_COEF = load_cam()


# --------------------------------------------------------------------------------------
# unit and conditions
# --------------------------------------------------------------------------------------
#: per-unit manufacturing tolerances, half-width of a uniform draw, relative unless [abs]
TOLERANCES = dict(
    kO=0.03, kC=0.03,              # spring rate, EN 13906-1 grade 1-2
    xO1=0.0010, xO0=0.0010, xC0=0.0015,  # [abs m] spring setting (nut, plate)
    J_shaft=0.02, m_contact=0.02,  # masses
    TOf=0.08, TCf=0.08,            # friction scatter of assembly
    caec=0.05,                     # puffer flow path
    cb=0.08, kb=0.05,              # buffer clearance / oil volume
    alpha0=0.005,                  # [abs rad] buffer engagement setting
    J1=0.02,
    lever_r=0.0003,                # [abs m] lever radius tolerance
    lever_beta=0.009,              # [abs rad] lever mounting angle (0.5 deg)
    gain=0.01,                     # transducer gain (+-1 %)
    zero_rad=0.002,                # transducer zero, rad-equivalent at the closed position
)


@dataclass
class Unit:
    """One simulated breaker (physical constants) and its travel sensor."""
    kO: float; xO0: float; xO1: float; rO: float; J_shaft: float; m_contact: float
    TOf: float; TCf: float; caec: float; raec: float; cb: float; kb: float; rb: float
    alpha0: float; kC: float; xC0: float; d: float; rC: float; J1: float; theta1_start: float
    lever_r: float = LEVER_R; lever_beta: float = LEVER_BETA
    gain: float = 1.0; zero_m: float = 0.0
    noise_sd_m: float = 0.0
    modes_hz: tuple = (650.0, 1650.0); modes_zeta: tuple = (0.03, 0.05)

    @property
    def J2(self) -> float:
        return self.J_shaft + self.m_contact * self.raec ** 2

    @property
    def zero_rad(self) -> float:
        return self.zero_m / (LEVER_R * math.cos(LEVER_BETA))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["J2"] = self.J2
        d["zero_rad"] = self.zero_rad
        return d


def design_unit() -> Unit:
    r = REFERENCE
    return Unit(kO=r["kO"], xO0=r["xO0"], xO1=r["xO1"], rO=r["rO"],
                J_shaft=r["J2"] - M_CONTACT * r["raec"] ** 2, m_contact=M_CONTACT,
                TOf=r["TOf"], TCf=r["TCf"], caec=r["caec"], raec=r["raec"], cb=r["cb"],
                kb=r["kb"], rb=r["rb"], alpha0=r["alpha0"], kC=r["kC"], xC0=r["xC0"],
                d=r["d"], rC=r["rC"], J1=r["J1"], theta1_start=r["theta1_start"])


def draw_unit(rng: np.random.Generator) -> Unit:
    """A manufactured unit: every constant within its tolerance (uniform), a sensor with
    its lever, gain and zero errors, noise level and torsional modes."""
    u = design_unit()
    t = TOLERANCES
    U = lambda w: rng.uniform(-w, w)
    for k in ("kO", "kC", "J_shaft", "m_contact", "TOf", "TCf", "caec", "cb", "kb", "J1"):
        setattr(u, k, getattr(u, k) * (1.0 + U(t[k])))
    for k in ("xO1", "xO0", "xC0", "alpha0"):
        setattr(u, k, getattr(u, k) + U(t[k]))
    u.lever_r = LEVER_R + U(t["lever_r"])
    u.lever_beta = LEVER_BETA + U(t["lever_beta"])
    u.gain = 1.0 + U(t["gain"])
    u.zero_m = U(t["zero_rad"]) * LEVER_R * math.cos(LEVER_BETA)
    # white noise of the transducer + its cable + ADC front end: 0.05-0.12 mm rms
    # (0.03-0.08 % FS), i.e. about 0.6-1.4 mrad at the shaft
    u.noise_sd_m = rng.uniform(0.05e-3, 0.12e-3)
    u.modes_hz = (float(rng.uniform(550.0, 750.0)), float(rng.uniform(1400.0, 1900.0)))
    u.modes_zeta = (float(rng.uniform(0.02, 0.04)), float(rng.uniform(0.03, 0.06)))
    return u


@dataclass
class Conditions:
    temperature_C: float = T_REF_C
    trigger_delay_s: float = 0.0


def draw_conditions(rng: np.random.Generator) -> Conditions:
    """Mechanism-cabinet temperature -10..40 C (outdoor cabinet with anti-condensation
    heater) and the delay from the recorder trigger to the start of motion, 0.5-3 ms
    (trip/close coil current rise plus latch release)."""
    return Conditions(temperature_C=float(rng.uniform(-10.0, 40.0)),
                      trigger_delay_s=float(rng.uniform(0.5e-3, 3.0e-3)))


def viscosity_ratio(temperature_C: float, B: float = OIL_B_K) -> float:
    T = temperature_C + 273.15
    return math.exp(B * (1.0 / T - 1.0 / (T_REF_C + 273.15)))


def buffer_temp_factor(temperature_C: float) -> float:
    """cb(T)/cb(20 C) of the linear buffer: laminar share proportional to viscosity."""
    return 1.0 + BUFFER_LAMINAR_SHARE * (viscosity_ratio(temperature_C) - 1.0)


def friction_temp_factor(temperature_C: float) -> float:
    return 1.0 + FRICTION_TEMP_COEFF * (temperature_C - T_REF_C)


def reduced_parameters(u: Unit, temperature_C: float = T_REF_C) -> dict:
    """The paper's reduced parameters (Eqs. 8 and 12) implied by the unit's constants at
    this temperature (buffer damping and friction torques temperature-corrected)."""
    J2 = u.J2
    TOf = u.TOf * friction_temp_factor(temperature_C)
    TCf = u.TCf * (1.0 + TCF_FRICTION_SHARE * (friction_temp_factor(temperature_C) - 1.0))
    cb = u.cb * buffer_temp_factor(temperature_C)
    AO = u.kO * u.rO ** 2 / J2
    return dict(
        AO=AO, BO=(u.kO * u.xO1 * u.rO - TOf) / J2, CO=u.caec * u.raec ** 2 / J2,
        DO=cb * u.rb ** 2 / J2, EO=u.kb * u.rb ** 2 / J2,
        AC=u.kC * u.rC * u.d / u.J1, BC=J2 / u.J1, CC=(TCf + u.kO * u.xO0 * u.rO) / J2, DC=AO,
    )
