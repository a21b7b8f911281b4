"""Physical constants of the prototype-B mechanism and the effect settings (all off by default).

Units: N, m, kg m², rad, s. Nothing here integrates anything; the dynamics live in
``opening_dynamics`` and ``closing_dynamics``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

# Constants spread per capture (the "spring, friction and buffer constants").
SPREAD_CONSTANTS = ("kO", "kC", "TOf", "TCf", "cb", "kb")

CONTACT_INERTIA_FRACTION = 0.3  # share of J2 on the contact side of the pull rod [-]
PUFFER_FILL_PRESSURE = 0.7e6    # SF6 filling pressure, absolute [Pa]


@dataclass(frozen=True)
class Mechanism:
    """Structure and state constants (the breaker file's Table 1 values, SI units).

    Attributes
    ----------
    kO, xO0, xO1, rO, J2, TOf, TCf : opening spring [N/m, m, m, m], output-shaft inertia
        [kg m²], resistance torques during opening and closing [N m].
    kC, xC0, d, rC, J1, theta1_start : closing spring [N/m, m, m, m], camshaft inertia [kg m²],
        latch-release angle [rad].
    caec, raec : puffer (arc chamber) damping [N s/m] and arm [m].
    cb, kb, rb, alpha0 : buffer damping [N s/m], stiffness [N/m], arm [m], engagement angle [rad].
    stroke : open rest angle measured from closed [rad].
    cam_knots, cam_coefficients : cam θ2 = h(θ1) as a cubic piecewise polynomial (closing
        coordinate, scipy PPoly layout) [rad].
    cam_rise_start, cam_rise_end : camshaft angles where the output shaft starts to move and
        reaches the closed position [rad].
    contact_fraction : share of J2 that sits on the contact side of the pull rod [-].
    """

    kO: float
    xO0: float
    xO1: float
    rO: float
    J2: float
    TOf: float
    TCf: float
    kC: float
    xC0: float
    d: float
    rC: float
    J1: float
    theta1_start: float
    caec: float
    raec: float
    cb: float
    kb: float
    rb: float
    alpha0: float
    stroke: float
    cam_knots: tuple
    cam_coefficients: tuple
    cam_rise_end: float
    cam_rise_start: float
    contact_fraction: float = CONTACT_INERTIA_FRACTION

    @classmethod
    def from_breaker(cls, breaker) -> "Mechanism":
        """Nominal constants of a ``service.mechanics.breaker.Breaker``."""
        names = ("kO", "xO0", "xO1", "rO", "J2", "TOf", "TCf", "kC", "xC0", "d", "rC", "J1",
                 "theta1_start", "caec", "raec", "cb", "kb", "rb", "alpha0", "stroke")
        cam = breaker.cam
        return cls(**{n: float(getattr(breaker, n)) for n in names},
                   cam_knots=tuple(float(x) for x in cam.theta1),
                   cam_coefficients=tuple(tuple(float(v) for v in col) for col in cam.coefficients.T),
                   cam_rise_end=float(cam.rise_end), cam_rise_start=float(cam.rise_start))

    def spread(self, rng: np.random.Generator, spread: float) -> "Mechanism":
        """A copy with each of SPREAD_CONSTANTS multiplied by U(1 - spread, 1 + spread)."""
        if spread <= 0:
            return self
        factors = rng.uniform(1.0 - spread, 1.0 + spread, size=len(SPREAD_CONSTANTS))
        return replace(self, **{n: getattr(self, n) * f for n, f in zip(SPREAD_CONSTANTS, factors)})

    @property
    def J_mech(self) -> float:
        """Inertia on the mechanism side of the pull rod [kg m²]."""
        return (1.0 - self.contact_fraction) * self.J2

    @property
    def J_contact(self) -> float:
        """Inertia on the contact side of the pull rod, referred to the output shaft [kg m²]."""
        return self.contact_fraction * self.J2

    def physical(self) -> dict:
        """The scalar constants, for a capture's truth record."""
        d = asdict(self)
        for k in ("cam_knots", "cam_coefficients"):
            d.pop(k)
        return d


@dataclass(frozen=True)
class Effects:
    """Settings of every effect; the defaults switch all of them off (the reduced physics).

    Opening buffer: ``buffer_exponent`` n of |v|^n (1 = linear), ``buffer_metering`` fractional
    orifice-area loss over the buffer span, ``buffer_free`` free travel before it bites [rad],
    ``buffer_vref`` speed at which the orifice law equals cb·v [m/s], ``buffer_span`` [rad].
    Puffer gas: ``gas_area`` piston area [m²] (0 = off), ``gas_kappa`` polytropic exponent,
    ``gas_ratio`` initial volume / swept volume, ``gas_leak`` nozzle leakage rate [1/s] before the nozzle clears at
    contact travel ``gas_clear`` [rad].
    Linkage: ratio 1 + a1 cos(k θ + φ1) + a2 cos(2k θ + φ2), mean-corrected over the stroke.
    Rod: ``rod_hz`` (None = rigid), ``rod_zeta``; ``sensor_side`` "mechanism" or "contact".
    Friction: ``coulomb_share`` share of TOf/TCf that is Coulomb friction (0: the paper's
    constant resistance torque), ``stribeck_rise`` = static/kinetic - 1, ``stribeck_speed`` [rad/s], ``stribeck_shape``.
    Viscous: ``viscous`` [N m s], ``viscous_slope`` (relative change over the stroke).
    Spring: ``spring_gamma`` relative force change at full compression, ``spring_power`` 1
    (quadratic) or 2 (cubic), ``spring_which`` "opening" or "closing".
    Sensor: ``sensor_kind`` None / "polynomial" / "eccentric", ``sensor_amp`` [rad],
    ``sensor_shape`` (cubic share or phase [rad]).
    Contact wipe (closing coordinate): ``wipe_touch`` [rad], ``wipe_peak`` wedge torque [N m],
    ``wipe_width`` [rad], ``wipe_friction`` [N m].
    Cam: ``cam_loss`` = 1 - efficiency at mid rise, ``cam_slope`` change of the loss along the rise.
    Outside the catalogue: ``sensor_lag`` time constant [s], ``latch_ramp`` torque ramp time [s].
    """

    buffer_exponent: float = 1.0
    buffer_metering: float = 0.0
    buffer_free: float = 0.0
    buffer_vref: float = 2.6
    buffer_span: float = 0.36
    gas_area: float = 0.0
    gas_kappa: float = 1.1
    gas_ratio: float = 2.0
    gas_leak: float = 30.0
    gas_clear: float = 0.55
    link_a1: float = 0.0
    link_a2: float = 0.0
    link_k: float = 2.0
    link_phi1: float = 0.0
    link_phi2: float = 0.0
    rod_hz: float | None = None
    rod_zeta: float = 0.05
    sensor_side: str = "mechanism"
    coulomb_share: float = 0.0
    stribeck_rise: float = 0.0
    stribeck_speed: float = 2.0
    stribeck_shape: float = 2.0
    viscous: float = 0.0
    viscous_slope: float = 0.0
    spring_gamma: float = 0.0
    spring_power: int = 1
    spring_which: str = "opening"
    sensor_kind: str | None = None
    sensor_amp: float = 0.0
    sensor_shape: float = 0.0
    wipe_touch: float = 0.8
    wipe_peak: float = 0.0
    wipe_width: float = 0.02
    wipe_friction: float = 0.0
    cam_loss: float = 0.0
    cam_slope: float = 0.0
    sensor_lag: float = 0.0
    latch_ramp: float = 0.0
