"""One prototype-B capture: simulate, pass through the travel transducer, add the vibration.

The capture looks like a recorder's: ~20 ms of rest before the motion, the latch-release shock
on the vibration channel just before it, the motion, ~30 ms of rest/rebound after the end of
the stroke, Gaussian travel noise and 16-bit coding over the 0..π transducer range.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from drivers.capture import Capture

from .closing_dynamics import simulate_closing_b
from .effects import EFFECTS, OPERATIONS, OUTSIDE, apply_effect, draw_shape
from .laws import Laws
from .mechanism import Effects, Mechanism
from .opening_dynamics import simulate_opening_b
from .reference import reference_mechanism

PRE_S = 0.02    # rest before the onset of motion [s]
POST_S = 0.03   # kept after the end of the stroke [s]
STOP_SPEED = 0.5  # an opening has stopped when the output shaft is slower than this [rad/s]


def simulate_motion(mech: Mechanism, eff: Effects, operation: str):
    """Simulate long enough to cover the stroke plus POST_S; returns (Motion, t_end_of_stroke [s])."""
    horizon = 0.11 if operation == "open" else 0.08
    for _ in range(4):
        if operation == "open":
            motion = simulate_opening_b(mech, eff, horizon)
            t_end = _opening_stop(motion, horizon)
        else:
            motion = simulate_closing_b(mech, eff, horizon)
            t_end = motion.events.get("latched", math.nan)
        if math.isfinite(t_end) and t_end + POST_S <= horizon:
            return motion, t_end
        horizon *= 1.6
    raise RuntimeError(f"the prototype-B {operation} did not complete its stroke within {horizon:.2f} s")


def _opening_stop(motion, horizon):
    t = np.arange(0.0, horizon, 2e-5)
    w = motion.sample(t)["omega"]
    k = int(np.argmax(w))
    below = np.nonzero(w[k:] <= STOP_SPEED)[0]
    return float(t[k + below[0]]) if below.size else math.nan


def vibration(t, events, rng, *, noise_g=0.6, full_scale_g=1000.0):
    """Mechanism acceleration [g]: decaying ringing bursts (time [s], peak [g], freq [Hz], decay [s])."""
    vib = rng.normal(0.0, noise_g, size=t.size)
    for t0, peak, freq, decay in events:
        on = t >= t0
        dt = t[on] - t0
        vib[on] += peak * np.exp(-dt / decay) * np.sin(2 * np.pi * freq * dt + 0.3)
    return np.clip(vib, -full_scale_g, full_scale_g)


def simulate_capture(operation: str, effect: str | None = None, strength: float = 0.0, *,
                     rng: np.random.Generator, spread: float = 0.06, noise_rad: float = 1.5e-3,
                     sample_rate_hz: float = 128000, mechanism: Mechanism | None = None,
                     trip: dict | None = None):
    """One capture of ``operation`` with ``effect`` at ``strength`` (None: a control).

    Parameters
    ----------
    operation : {"open", "close"}
    effect : str or None
        One of EFFECTS or OUTSIDE, acting on ``operation`` (see OPERATIONS).
    strength : float
        0 = the reduced model's form, 1 = realistic (see REALISTIC).
    rng : numpy.random.Generator
        Draws the constants' spread, the effect's shape, the noise and the vibration.
    spread : float
        Uniform relative spread of kO, kC, TOf, TCf, cb, kb around nominal [-].
    noise_rad : float
        Travel noise standard deviation [rad].
    sample_rate_hz : float
    mechanism : Mechanism, optional
        Nominal constants; the reference 252 kV breaker when omitted.
    trip : dict, optional
        An opening's trip strike before this capture's own latch-release shock, from the blind
        generator ``service.prototypes.trip_strike_blind.add_trip`` (its physics untouched):
        ``latch_time_s`` [s, strike to motion] and ``strike_g`` [g] (optional ``rub_rms_g``,
        ``seed``). The release stays B's own shock (the blind release is given 0 g). The truth
        then carries ``latch_time_s`` and ``t_strike_s``. Omitted: the capture is as before.

    Returns
    -------
    (Capture, truth) : travel [rad from closed] and vibration [g]; truth is a JSON-ready dict.
    """
    if operation not in ("open", "close"):
        raise ValueError(f"operation must be 'open' or 'close', got {operation!r}")
    if effect is not None:
        if effect not in EFFECTS + OUTSIDE:
            raise ValueError(f"unknown effect {effect!r}; known: {', '.join(EFFECTS + OUTSIDE)}")
        if operation not in OPERATIONS[effect]:
            raise ValueError(f"effect {effect} acts only on {' and '.join(OPERATIONS[effect])} operations, "
                             f"not on {operation}")
    if mechanism is None:
        mechanism = reference_mechanism()
    mech = mechanism.spread(rng, spread)
    shape = draw_shape(effect, operation, rng) if effect is not None else {}
    eff = apply_effect(Effects(), effect, strength, shape)
    motion, t_stroke = simulate_motion(mech, eff, operation)

    fs = float(sample_rate_hz)
    n = int(round((PRE_S + t_stroke + POST_S) * fs))
    t_abs = np.arange(n) / fs
    obs = motion.sample(t_abs - PRE_S)
    true_travel = obs["travel"]
    laws = Laws(mech, eff)
    travel = true_travel + laws.sensor_error(true_travel)
    if eff.sensor_lag > 0:
        a = math.exp(-1.0 / (fs * eff.sensor_lag))
        travel, _ = lfilter([1.0 - a], [1.0, -a], travel, zi=[a * travel[0]])
    travel = travel + rng.normal(0.0, noise_rad, size=n)
    lsb = np.pi / (2**16 - 1)
    travel = np.round(travel / lsb) * lsb

    lead = rng.uniform(0.3e-3, 0.5e-3)
    shock = rng.uniform(350.0, 500.0)
    bursts = [(PRE_S - lead, shock, rng.uniform(2200.0, 2800.0), rng.uniform(0.5e-3, 0.8e-3))]
    ev = {k: float(v) for k, v in motion.events.items()}
    if operation == "open":
        if "buffer" in ev:
            bursts.append((PRE_S + ev["buffer"], shock * rng.uniform(0.4, 0.6), rng.uniform(1900, 2400), 0.7e-3))
        bursts.append((PRE_S + t_stroke, shock * rng.uniform(0.1, 0.2), rng.uniform(1500, 2000), 0.6e-3))
    else:
        if "touch" in ev:
            bursts.append((PRE_S + ev["touch"], shock * rng.uniform(0.2, 0.35), rng.uniform(2500, 3200), 0.5e-3))
        bursts.append((PRE_S + t_stroke, shock * rng.uniform(0.5, 0.7), rng.uniform(1600, 2100), 0.8e-3))
    vib = vibration(t_abs, bursts, rng)
    trip_truth = None
    if trip is not None and operation == "open":
        from service.prototypes.trip_strike_blind import add_trip

        vib, trip_truth = add_trip(t_abs, vib, t_motion=PRE_S, latch_time=float(trip["latch_time_s"]),
                                   strike_peak_g=float(trip["strike_g"]), release_peak_g=0.0, release_lead=lead,
                                   rub_rms_g=trip.get("rub_rms_g"), rng=np.random.default_rng(trip.get("seed")))

    cap = Capture(travel=travel, sample_rate=fs, vibration=vib, source=f"prototype-b-{operation}",
                  travel_limits=(0.0, math.pi), vibration_limits=(-1000.0, 1000.0))
    truth = {
        "operation": operation, "effect": effect, "strength": float(strength),
        "outside_catalogue": effect in OUTSIDE,
        "shape": _jsonable(shape), "constants": _jsonable(mech.physical()),
        "t_shock_s": PRE_S - lead, "t_motion_s": PRE_S, "t_end_of_stroke_s": PRE_S + t_stroke,
        "events_s": {k: PRE_S + v for k, v in ev.items()},
        "noise_rad": float(noise_rad), "spread": float(spread),
    }
    if trip_truth is not None:
        truth["latch_time_s"], truth["t_strike_s"] = trip_truth.latch_time, trip_truth.t_strike
    return cap, truth


def _jsonable(d: dict) -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, (np.floating, float)):
            out[k] = float(v)
        elif isinstance(v, (np.integer, int)) and not isinstance(v, bool):
            out[k] = int(v)
        elif isinstance(v, np.str_):
            out[k] = str(v)
        else:
            out[k] = v
    return out
