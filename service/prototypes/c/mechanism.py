"""Prototype C: the breaker's design constants, one unit's drawn constants, the cam, the reduced parameters.

Units are SI throughout (m, N, N m, kg m^2, rad, s). The design values are the reference 252 kV
breaker (paper Table 1, with xC0 = 0.37 m, see /work/shared/reference/reference-252kV.toml).
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

# Reference design (Table 1). Geometry (arms, crank lengths) is structural and not drawn per unit.
DESIGN = {
    "kC": 90e3, "xC0": 0.37, "d": 0.29, "rC": 0.086, "J1": 0.095, "theta1_start": 0.20,
    "kO": 130e3, "xO1": 0.17, "rO": 0.08, "J2": 0.243, "TCf": 1600.0, "TOf": 600.0,
    "caec": 1000.0, "raec": 0.15, "cb": 1500.0, "kb": 150e3, "rb": 0.08, "alpha0": 0.698,
}
# State constants that a real unit's manufacturing tolerance scatters (make_unit draws them).
DRAWN = ("kC", "xC0", "J1", "kO", "xO1", "J2", "TCf", "TOf", "caec", "cb", "kb", "alpha0")
STROKE_RAD = 1.0          # closed (travel 0) to open (travel 1): the cam's closing coordinate range

CAM_CSV = Path(__file__).with_name("cam-profile.csv")


@dataclass(frozen=True)
class Cam:
    """theta2 = h(theta1) in the closing coordinate (0 open, 1 closed); C2 cubic spline."""

    h: CubicSpline
    dh: CubicSpline
    d2h: CubicSpline
    theta1_end: float     # first camshaft angle where the profile reaches its top [rad]
    d2h_max: float        # max |h''| over the lift [1/rad], for normalising cam curvature

    def __post_init__(self):
        object.__setattr__(self, "_knots", self.h.x.tolist())
        object.__setattr__(self, "_coef", [tuple(col) for col in self.h.c.T.tolist()])

    def eval3(self, q: float):
        """(h, h', h'') at one camshaft angle q [rad]; a scalar fast path of the spline."""
        x, c = self._knots, self._coef
        i = min(max(bisect_right(x, q) - 1, 0), len(x) - 2)
        dx = q - x[i]
        a3, a2, a1, a0 = c[i]
        return (((a3 * dx + a2) * dx + a1) * dx + a0, (3 * a3 * dx + 2 * a2) * dx + a1, 6 * a3 * dx + 2 * a2)


@lru_cache(maxsize=1)
def cam() -> Cam:
    """The reference cam (211-point table interpolated by a C2 cubic spline)."""
    table = np.loadtxt(CAM_CSV, delimiter=",", skiprows=1)
    h = CubicSpline(table[:, 0], table[:, 1])
    top = table[:, 1].max()
    end = float(table[np.argmax(table[:, 1] >= top - 1e-9), 0])
    grid = np.linspace(table[0, 0], end, 2000)
    d2h = h.derivative(2)
    return Cam(h=h, dh=h.derivative(1), d2h=d2h, theta1_end=end, d2h_max=float(np.abs(d2h(grid)).max()))


@dataclass(frozen=True)
class Unit:
    """One physical breaker: its constants, its effects {name: strength} and their fixed shapes."""

    constants: dict
    effects: dict = field(default_factory=dict)
    shapes: dict = field(default_factory=dict)

    def strength(self, name: str) -> float:
        return float(self.effects.get(name, 0.0))


def draw_constants(rng: np.random.Generator, tolerance: float) -> dict:
    """Design constants with each DRAWN one scattered uniformly within ±tolerance (relative)."""
    if not (0.0 <= tolerance < 0.5):
        raise ValueError(f"tolerance must be a relative spread in [0, 0.5), got {tolerance!r}")
    c = dict(DESIGN)
    for name in DRAWN:
        c[name] = DESIGN[name] * (1.0 + rng.uniform(-tolerance, tolerance))
    c["xO0"] = c["xO1"] - c["rO"] * STROKE_RAD   # spring compression at the open position
    # fraction of J2 that sits on the contact side of the linkage (pull rod, contact, puffer)
    c["contact_share"] = float(rng.uniform(0.45, 0.65))
    return c


def applied(constants: dict, conditions: dict) -> dict:
    """Constants as they act in one capture: friction, buffer oil, puffer and spring charge applied."""
    c = dict(constants)
    c["TOf"] *= conditions["friction"]
    c["TCf"] *= conditions["friction"]
    c["cb"] *= conditions["buffer_damping"]
    c["caec"] *= conditions["puffer"]
    c["xO0"] = constants["xO0"] * conditions["spring_charge"]
    c["xO1"] = c["xO0"] + c["rO"] * STROKE_RAD
    c["xC0"] = constants["xC0"] * conditions["spring_charge"]
    return c


def reduced_params(c: dict, operation: str) -> dict:
    """The paper's reorganised parameters (Eq. 8 and 12) implied by applied constants ``c``.

    AO, BO, EO [s^-2], CO, DO [s^-1]; AC, CC [s^-2], BC [-].
    """
    if operation == "open":
        return {"AO": c["kO"] * c["rO"] ** 2 / c["J2"],
                "BO": (c["kO"] * c["xO1"] * c["rO"] - c["TOf"]) / c["J2"],
                "CO": c["caec"] * c["raec"] ** 2 / c["J2"],
                "DO": c["cb"] * c["rb"] ** 2 / c["J2"],
                "EO": c["kb"] * c["rb"] ** 2 / c["J2"]}
    return {"AC": c["kC"] * c["rC"] * c["d"] / c["J1"],
            "BC": c["J2"] / c["J1"],
            "CC": (c["TCf"] + c["kO"] * c["xO0"] * c["rO"]) / c["J2"]}


def closing_lever(theta1, c: dict):
    """Closing-spring compression x [m] and lever l [m] (torque = F(x) l) at camshaft angle theta1.

    The spring acts on a crank rC through a chain anchored d from the camshaft; for a small chain
    angle the compression falls by rC (1 - cos theta1) and the arm is rC d sin / (d + rC cos).
    """
    x = c["xC0"] - c["rC"] * (1.0 - np.cos(theta1))
    lever = c["rC"] * c["d"] * np.sin(theta1) / (c["d"] + c["rC"] * np.cos(theta1))
    return x, lever
