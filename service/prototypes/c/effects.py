"""Prototype C's effects: names, where they act, their shapes (drawn once per unit) and force laws.

Every law takes the strength ``s`` (0 = absent, 1 = realistic for a breaker in service) and is
exactly the reduced model's term at s = 0. Torques are on the output shaft [N m] unless said.
The forms and ranges are this prototype's own; docs/prototype-c.md lists them.
"""

from __future__ import annotations

import math

import numpy as np

EFFECTS = ("orifice_buffer", "puffer_gas", "linkage_kinematics", "rod_elasticity", "stribeck_friction",
           "viscous_friction", "spring_nonlinearity", "sensor_nonlinearity", "contact_wipe", "cam_friction")
OUTSIDE = ("sensor_lag", "latch_ramp")
OPERATIONS = {
    "orifice_buffer": ("open",), "puffer_gas": ("open",),
    "linkage_kinematics": ("open", "close"), "rod_elasticity": ("open", "close"),
    "stribeck_friction": ("open", "close"), "viscous_friction": ("open", "close"),
    "spring_nonlinearity": ("open", "close"), "sensor_nonlinearity": ("open", "close"),
    "contact_wipe": ("close",), "cam_friction": ("close",),
    "sensor_lag": ("open", "close"), "latch_ramp": ("open", "close"),
}
REALISTIC = {
    "orifice_buffer": "The buffer oil passes an orifice, so 20-40 % of its damping goes with speed squared "
                      "and fades as the shaft slows in the buffer: more overtravel, later end of stroke.",
    "puffer_gas": "1-2.5 % of the puffer force is SF6 compressed polytropically and bled through the nozzle "
                  "(a gas spring) instead of linear damping: the stroke runs ahead early and lags late.",
    "linkage_kinematics": "The contact-side inertia is reflected through a crank whose ratio varies with angle, "
                          "so the effective inertia varies about ±5-10 % over the stroke (plus its omega^2 term).",
    "rod_elasticity": "A quarter to 45 % of the moving inertia sits behind an elastic pull rod ringing at "
                      "150-300 Hz; latch release and buffer engagement excite mrad-level ringing.",
    "stribeck_friction": "8-15 % of the transmission friction follows the spring load and has a 1.4-2x "
                         "static breakaway falling within 0.1-0.4 rad/s: opening starts slower, ends faster.",
    "viscous_friction": "A speed-proportional bearing/seal drag worth 1.5-3 % of the constant friction at "
                        "30 rad/s (about peak speed): the whole stroke runs a little slower.",
    "spring_nonlinearity": "The springs' force departs by 1-2.5 % from Hooke's law, progressive or degressive "
                           "about mid-stroke (tanh law), which reshapes the acceleration over the stroke.",
    "sensor_nonlinearity": "The travel transducer reads true angle plus a few mrad of smooth error "
                           "(quadratic gain error and a ripple), zero at the closed position.",
    "contact_wipe": "The moving contact enters the fixed fingers 0.12-0.20 rad before closed: an insertion "
                    "wedge then wipe friction slow the last part of the closing stroke.",
    "cam_friction": "Cam-roller friction costs 0.6-1.2 % of the transmitted cam torque (up to twice that "
                    "where the cam is sharply curved), so the closing runs slower.",
    "sensor_lag": "OUTSIDE the catalogue: the transducer follows the true travel with a first-order lag "
                  "of 0.25-0.5 ms.",
    "latch_ramp": "OUTSIDE the catalogue: the latch lets the driving spring torque in over a 1-2 ms ramp "
                  "instead of at once, delaying and softening the start.",
}

MAX_STRENGTH = 3.0      # beyond 3x a realistic level the laws leave their physical range


def check_effects(effects) -> dict:
    """{name: strength} validated: known names, finite strengths in [0, MAX_STRENGTH]."""
    if effects is None:
        return {}
    if not isinstance(effects, dict):
        raise ValueError(f"effects must be a dict {{name: strength}}, got {type(effects).__name__}")
    out = {}
    for name, strength in effects.items():
        if name not in OPERATIONS:
            raise ValueError(f"unknown effect {name!r}; prototype C knows {', '.join(EFFECTS + OUTSIDE)}")
        try:
            s = float(strength)
        except (TypeError, ValueError):
            raise ValueError(f"strength of {name!r} must be a number, got {strength!r}") from None
        if not (math.isfinite(s) and 0.0 <= s <= MAX_STRENGTH):
            raise ValueError(f"strength of {name!r} must be in [0, {MAX_STRENGTH}], got {strength!r}")
        out[name] = s
    return out


def check_operation(effects: dict, operation: str) -> None:
    """Raise ValueError when an effect with strength > 0 does not act in ``operation``."""
    if operation not in ("open", "close"):
        raise ValueError(f"operation must be 'open' or 'close', got {operation!r}")
    wrong = [n for n, s in effects.items() if s > 0 and operation not in OPERATIONS[n]]
    if wrong:
        raise ValueError(f"effect(s) {', '.join(wrong)} act only in "
                         f"{'/'.join(OPERATIONS[wrong[0]])}, not in a {operation} operation")


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _signed(rng, lo, hi):
    return float(rng.choice((-1.0, 1.0)) * rng.uniform(lo, hi))


def draw_shapes(rng: np.random.Generator, effects: dict) -> dict:
    """Shape parameters of every effect present (drawn once; fixed for the unit)."""
    draw = {
        "orifice_buffer": lambda: {"laminar_share": _u(rng, 0.60, 0.80), "ref_speed_factor": _u(rng, 1.00, 1.30)},
        "puffer_gas": lambda: {"volume_per_rad": _u(rng, 0.45, 0.65), "polytropic_n": _u(rng, 1.10, 1.30),
                               "energy_ratio": _u(rng, 0.95, 1.30),
                               "gas_share": _u(rng, 0.010, 0.025)},
        "linkage_kinematics": lambda: {"crank_angle_closed": _u(rng, 1.0, 1.4), "share": _u(rng, 0.35, 0.55)},
        "rod_elasticity": lambda: {"elastic_share": _u(rng, 0.25, 0.45), "freq_hz": _u(rng, 150.0, 300.0),
                                   "damping_ratio": _u(rng, 0.03, 0.08)},
        "stribeck_friction": lambda: {"load_share": _u(rng, 0.08, 0.15), "breakaway_ratio": _u(rng, 1.4, 2.0),
                                      "stribeck_speed": _u(rng, 0.10, 0.40), "exponent": _u(rng, 1.0, 2.0)},
        "viscous_friction": lambda: {"share_at_30rad_s": _u(rng, 0.015, 0.03), "camshaft_ratio": _u(rng, 0.05, 0.15)},
        "spring_nonlinearity": lambda: {"gamma_opening": _signed(rng, 0.01, 0.025),
                                        "gamma_closing": _signed(rng, 0.01, 0.025), "width": _u(rng, 0.6, 1.2)},
        "sensor_nonlinearity": lambda: {"quad_mrad": _signed(rng, 3.0, 6.0), "ripple_mrad": _u(rng, 1.0, 2.5),
                                        "ripple_period_rad": _u(rng, 0.45, 0.90)},
        "contact_wipe": lambda: {"wipe_rad": _u(rng, 0.12, 0.20), "insertion_rad": _u(rng, 0.01, 0.03),
                                 "peak_nm": _u(rng, 450.0, 900.0), "wipe_nm": _u(rng, 250.0, 450.0)},
        "cam_friction": lambda: {"mu": _u(rng, 0.006, 0.012), "curvature_gain": _u(rng, 0.3, 1.0)},
        "sensor_lag": lambda: {"tau_ms": _u(rng, 0.25, 0.5)},
        "latch_ramp": lambda: {"ramp_ms": _u(rng, 1.0, 2.0)},
    }
    return {name: draw[name]() for name in effects}


# ---- force laws (pure functions; s = strength, sh = that effect's shape dict) ----

def linkage_inertia(theta, s, sh):
    """(lambda, dlambda/dtheta): rigid-side inertia multiplier [-] and its slope [1/rad].

    The contact-side share of the inertia is reflected by the squared ratio of a crank at angle
    beta0 + theta (travel coordinate), normalised to mean 1 over the stroke so s only reshapes.
    """
    if s == 0.0:
        return 1.0, 0.0
    b0, a = sh["crank_angle_closed"], sh["share"]
    mean = 0.5 - (math.sin(2 * (b0 + 1.0)) - math.sin(2 * b0)) / 4.0   # mean of sin^2 over [0, 1]
    sn = math.sin(b0 + theta)
    lam = 1.0 + s * a * (sn * sn / mean - 1.0)
    dlam = s * a * math.sin(2 * (b0 + theta)) / mean
    return lam, dlam


def spring_force(k, x, x_lo, x_hi, s, gamma, width):
    """Spring force [N] at compression x [m]: k x (1 + s gamma tanh((x - mid) / (width half-range)))."""
    if s == 0.0:
        return k * x
    mid, half = 0.5 * (x_lo + x_hi), 0.5 * (x_hi - x_lo) * width
    return k * x * (1.0 + s * gamma * math.tanh((x - mid) / half))


def stribeck_factor(omega, load_ratio, s, sh, eps=0.02):
    """Multiplier on the constant friction torque: part follows load and a Stribeck speed curve.

    (1 - s q) + s q load_ratio g(|w|) / g_inf, g = 1 + (beta - 1) exp(-(|w|/w_s)^delta);
    the sign of motion is carried by the caller. eps [rad/s] regularises nothing here.
    """
    if s == 0.0:
        return 1.0
    q, beta = sh["load_share"], sh["breakaway_ratio"]
    g = 1.0 + (beta - 1.0) * math.exp(-(abs(omega) / sh["stribeck_speed"]) ** sh["exponent"])
    return (1.0 - s * q) + s * q * load_ratio * g


def viscous_coeff(tof_design, s, sh):
    """Output-shaft viscous coefficient [N m s/rad]: share of TOf at 30 rad/s (about peak speed)."""
    return s * sh["share_at_30rad_s"] * tof_design / 30.0


def buffer_damping_torque(omega, c_lin, s, sh, omega_eng):
    """Buffer damping torque [N m]; c_lin = cb rb^2 [N m s/rad]; omega_eng = nominal engagement speed.

    Orifice: a share 1 - laminar_share**s of the damping goes as omega|omega| / (f omega_eng), the
    rest stays linear (laminar leakage); the share saturates below 1 for strong effects.
    """
    if s == 0.0:
        return c_lin * omega
    share = 1.0 - sh["laminar_share"] ** s      # orifice share: 1 - laminar share at s = 1, < 1 always
    ref = sh["ref_speed_factor"] * omega_eng
    return c_lin * omega * ((1.0 - share) + share * abs(omega) / ref)


def contact_torque(travel_c, omega_c, s, sh):
    """Contact insertion + wipe torque [N m] opposing closing; travel_c = contact-side travel [rad].

    z = wipe - travel_c is the insertion depth; wedge force z/zi exp(1 - z/zi) peaks at zi,
    wipe friction (1 - exp(-z/zi)) opposes the (closing, travel-decreasing) motion.
    """
    if s == 0.0:
        return 0.0
    z = sh["wipe_rad"] - travel_c
    if z <= 0.0:
        return 0.0
    zi = sh["insertion_rad"]
    wedge = sh["peak_nm"] * (z / zi) * math.exp(1.0 - z / zi)
    wipe = sh["wipe_nm"] * (1.0 - math.exp(-z / zi)) * math.tanh(omega_c / 0.05)
    return s * (wedge + wipe)


def cam_mu(d2h, d2h_max, s, sh):
    """Cam-roller friction as a share of the transmitted camshaft torque [-]."""
    if s == 0.0:
        return 0.0
    return s * sh["mu"] * (1.0 + sh["curvature_gain"] * abs(d2h) / d2h_max)


def sensor_error(theta, s, sh):
    """Transducer error [rad] at true travel theta [rad]; 0 at closed (theta = 0)."""
    if s == 0.0:
        return np.zeros_like(theta)
    return s * 1e-3 * (sh["quad_mrad"] * theta ** 2
                       + sh["ripple_mrad"] * np.sin(2 * np.pi * theta / sh["ripple_period_rad"]))


def rod_params(J_total, s, sh):
    """(J_rigid, J_elastic, K [N m/rad], C [N m s/rad]) of the elastic pull rod at strength s."""
    je = (1.0 - (1.0 - sh["elastic_share"]) ** s) * J_total    # e0 at s = 1, below J_total always
    jr = J_total - je
    mu = jr * je / J_total
    wn = 2 * math.pi * sh["freq_hz"]
    return jr, je, wn * wn * mu, 2.0 * sh["damping_ratio"] * wn * mu
