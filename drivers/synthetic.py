"""Synthetic operation captures from the project's own models: travel with sensor noise and
quantisation, and a vibration channel with the latch-release shock, the buffer impact and the
end-of-travel impact. Used by the device emulators, the demo, the studies and the tests.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from service.mechanics.breaker import Breaker
from service.mechanics.closing import simulate_closing
from service.mechanics.opening import simulate_opening
from drivers.capture import Capture

SHOCK_LEAD_S = 0.4e-3  # latch-release shock precedes the onset of motion [s]


@dataclass(frozen=True)
class SyntheticTruth:
    """What the generator knows about the capture it made.

    Attributes
    ----------
    operation : str
        ``open`` or ``close``.
    params : dict
        Model parameters used.
    t_shock, t_motion, t_peak : float
        Latch shock, onset of motion and end of the valid interval [s from the first sample].
    noise_rad : float
        Travel noise standard deviation [rad].
    """

    operation: str
    params: dict
    t_shock: float
    t_motion: float
    t_peak: float
    noise_rad: float


def operation_travel(breaker: Breaker, operation: str, params: Mapping[str, float], t,
                     *, simulate: Callable | None = None):
    """Noise-free travel [rad from closed] at ``t`` [s since motion onset], and the peak time [s].

    ``simulate`` replaces the reduced model (the virtual prototype passes its own); it takes
    ``(params, t)`` and returns a ``Trajectory`` in the operation's own coordinate.
    """
    t = np.asarray(t, dtype=float)
    if simulate is None:
        if operation == "open":
            def simulate(p, tt):
                return simulate_opening(p, tt, CO=breaker.CO, alpha0=breaker.alpha0)
        else:
            def simulate(p, tt):
                return simulate_closing(p, tt, cam=breaker.cam, geometry=breaker.closing_geometry)
    tr = simulate(params, t).raise_for_status()
    theta = np.where(t < 0, 0.0, tr.theta)
    if operation == "open":
        return theta, tr.t_peak, tr
    # Closing coordinate θ2 (0 = open) to travel from the closed position.
    theta2 = np.where(t < 0, breaker.cam.theta2[0], tr.theta)
    return breaker.stroke - theta2, tr.t_peak, tr


def vibration_signature(t, events, rng, *, noise_g=0.6, full_scale_g=1000.0):
    """Mechanism acceleration [g]: decaying bursts at each event (time [s], peak [g], freq [Hz])."""
    vib = rng.normal(0.0, noise_g, size=t.size)
    for t0, peak, freq in events:
        if not np.isfinite(t0):
            continue
        dt = t - t0
        on = dt >= 0
        tau = 0.6e-3
        vib[on] += peak * np.exp(-dt[on] / tau) * np.sin(2 * np.pi * freq * dt[on])
    return np.clip(vib, -full_scale_g, full_scale_g)


def synthesize_capture(breaker: Breaker, operation: str, params: Mapping[str, float], *,
                       rng: np.random.Generator, fs: float = 128_000.0, pre_s: float = 0.02,
                       post_s: float = 0.03, noise_rad: float = 0.0015, bits: int | None = 16,
                       shock_g: float = 420.0, simulate: Callable | None = None,
                       shock_lead_s: float = SHOCK_LEAD_S) -> tuple[Capture, SyntheticTruth]:
    """Make one capture of an operation with known truth.

    Parameters
    ----------
    breaker : Breaker
    operation : {"open", "close"}
    params : mapping
        Model parameters (AO, BO, DO, EO for opening; AC, BC, CC, DC for closing).
    rng : numpy.random.Generator
    fs : float
        Sample rate [Hz].
    pre_s : float
        Idle time before the onset of motion [s].
    post_s : float
        Time kept after the valid interval ends [s].
    noise_rad : float
        Gaussian travel noise [rad].
    bits : int or None
        Quantise the travel to this many bits over the sensor's 0..π range (None: no quantisation).
    shock_g : float
        Peak latch-release shock [g] (clips at ±1000 g like the real sensor).
    simulate : callable, optional
        Alternative simulator ``(params, t) -> Trajectory`` (virtual prototype).
    """
    if operation not in ("open", "close"):
        raise ValueError(f"operation must be 'open' or 'close', got {operation!r}")
    horizon = 0.2
    t_probe = np.arange(0.0, horizon, 1.0 / fs)
    _, t_peak, _ = operation_travel(breaker, operation, params, t_probe, simulate=simulate)
    if not np.isfinite(t_peak):
        raise ValueError("the simulated operation never reached its end position")
    n = int(round((pre_s + t_peak + post_s) * fs))
    t_abs = np.arange(n) / fs
    t_rel = t_abs - pre_s
    travel, _, tr = operation_travel(breaker, operation, params, t_rel, simulate=simulate)
    travel = travel + rng.normal(0.0, noise_rad, size=n)
    if bits:
        lsb = np.pi / (2**bits - 1)
        travel = np.round(travel / lsb) * lsb
    t_shock = pre_s - shock_lead_s
    events = [(t_shock, shock_g, 2500.0), (pre_s + t_peak, 0.3 * shock_g, 1800.0)]
    if operation == "open":
        events.append((pre_s + tr.events.get("buffer_engaged", np.nan), 0.6 * shock_g, 2200.0))
    vib = vibration_signature(t_abs, events, rng)
    cap = Capture(travel=travel, sample_rate=fs, vibration=vib, source=f"synthetic-{operation}",
                  travel_limits=(0.0, np.pi), vibration_limits=(-1000.0, 1000.0))
    truth = SyntheticTruth(operation, dict(params), t_shock, pre_s, pre_s + t_peak, noise_rad)
    return cap, truth
