"""Prototype A's trip: the trip-coil armature striking the latch, before the latch releases.

A spring mechanism opens in three mechanical steps the accelerometer hears: the energised trip
coil's armature strikes the trip latch (a light part hitting a small one: a short, high-pitched
ring of some tens of g); the latch slides off its pawl against the friction of its grease; the
released opening spring then knocks the mechanism (the loud latch-release shock, already in the
captures ``drivers.synthetic`` makes, 0.4 ms before motion) and the shaft starts to move.

The latch time is the strike-to-motion time. It grows when the latch's grease dries or dirt and
corrosion stick it: the latch then slides slower, and may stutter (small rubbing bursts between
strike and release). :func:`add_trip_strike` adds the strike (and that rubbing) to a vibration
array; :func:`sticking_latch_time` is the latch time of a latch that sticks more each opening.
"""

from __future__ import annotations

import numpy as np

HEALTHY_LATCH_S = 1.2e-3
"""Strike-to-motion time of a clean, greased latch [s]: armature strike, a ~0.8 ms slide, and
the 0.4 ms from the release shock to motion."""
STRIKE_G = 30.0
"""The strike's peak [g]: well under the latch-release shock (~420 g) and under the trigger's
50 g shock threshold, so the capture still triggers (and the fit's window still starts) at the
release."""
STRIKE_HZ = 4800.0
"""Ring frequency of the strike [Hz]: the trip latch is a small, stiff part."""
STRIKE_DECAY_S = 0.3e-3
"""Decay time constant of the strike's ring [s]."""


def add_trip_strike(vibration, sample_rate: float, t_motion_s: float, latch_time_s: float,
                    rng: np.random.Generator, *, strike_g: float = STRIKE_G, rubbing: float = 0.0,
                    full_scale_g: float = 1000.0) -> np.ndarray:
    """The vibration [g] with the trip strike added at ``t_motion_s - latch_time_s``.

    Parameters
    ----------
    vibration : array_like
        Mechanism acceleration [g] (noise, release shock and impacts already in it).
    sample_rate : float
        [Hz]
    t_motion_s : float
        Start of shaft motion [s from the first sample].
    latch_time_s : float
        Strike-to-motion time [s].
    rng : numpy.random.Generator
        Draws the strike's phase and the rubbing's instants.
    strike_g : float
        Peak of the strike [g].
    rubbing : float
        0 = a clean slide; up to 1 = a sticking latch that stutters: bursts of up to a fifth of
        the strike's peak between strike and release [-].
    full_scale_g : float
        The channel's clipping level [g].
    """
    v = np.array(vibration, dtype=float, copy=True)
    t = np.arange(v.size) / float(sample_rate)
    t_strike = float(t_motion_s) - float(latch_time_s)
    bursts = [(t_strike, strike_g, STRIKE_HZ, STRIKE_DECAY_S, rng.uniform(0.0, 2 * np.pi))]
    if rubbing > 0:
        span = max(float(latch_time_s) - 0.8e-3, 0.0)
        for _ in range(int(rng.integers(1, 4))):
            bursts.append((t_strike + 0.4e-3 + rng.uniform(0.0, span), rubbing * 0.2 * strike_g * rng.uniform(0.5, 1.0),
                           rng.uniform(3000.0, 4000.0), 0.2e-3, rng.uniform(0.0, 2 * np.pi)))
    for t0, peak, freq, decay, phase in bursts:
        on = t >= t0
        dt = t[on] - t0
        # the armature's contact rises over a quarter period, then rings down
        rise = 1.0 - np.exp(-dt * freq * 4.0)
        v[on] += peak * rise * np.exp(-dt / decay) * np.sin(2 * np.pi * freq * dt + phase)
    return np.clip(v, -full_scale_g, full_scale_g)


def sticking_latch_time(opening: int, *, start: int, per_opening_s: float,
                        healthy_s: float = HEALTHY_LATCH_S) -> float:
    """Latch time [s] at ``opening`` (0-based) of a latch that sticks ``per_opening_s`` [s] more
    each opening from opening ``start`` on."""
    return healthy_s + max(0, opening - start + 1) * per_opening_s if opening >= start else healthy_s
