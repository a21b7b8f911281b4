"""Prototype C's measurement chain: transducer error and lag, noise, 16-bit quantisation, vibration."""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from . import effects as fx

TRAVEL_SPAN = (-0.15, 1.25)     # transducer range [rad]; 16 bits over it (~21 µrad a step)
VIBRATION_SPAN = (-1000.0, 1000.0)   # accelerometer range [g]
VIBRATION_NOISE_G = 0.3         # accelerometer noise sd [g]


def quantise(x: np.ndarray, span: tuple, bits: int = 16) -> np.ndarray:
    """Round to a ``bits``-bit grid over ``span`` and clip to it."""
    lo, hi = span
    step = (hi - lo) / (2 ** bits - 1)
    return np.clip(lo + np.round((x - lo) / step) * step, lo, hi)


def transducer(true_travel: np.ndarray, effects: dict, shapes: dict, sample_rate: float) -> np.ndarray:
    """What the travel transducer reports [rad] before noise: nonlinearity, then (outside) lag."""
    out = true_travel + fx.sensor_error(true_travel, effects.get("sensor_nonlinearity", 0.0),
                                        shapes.get("sensor_nonlinearity"))
    s_lag = effects.get("sensor_lag", 0.0)
    if s_lag > 0:
        tau = s_lag * shapes["sensor_lag"]["tau_ms"] * 1e-3
        a = np.exp(-1.0 / (sample_rate * tau))        # exact first-order lag for a held input
        out = lfilter([1.0 - a], [1.0, -a], out, zi=[a * out[0]])[0]
    return out


def record_travel(true_travel, effects, shapes, sample_rate, noise_rad, rng) -> np.ndarray:
    """Transducer reading + Gaussian noise [rad], 16-bit quantised."""
    read = transducer(true_travel, effects, shapes, sample_rate)
    return quantise(read + rng.normal(0.0, noise_rad, read.size), TRAVEL_SPAN)


def burst(t: np.ndarray, t0: float, amp_g: float, freq_hz: float, tau_s: float) -> np.ndarray:
    """A decaying sinusoid starting at t0 [s]: the ring of a structure struck at t0."""
    dt = t - t0
    out = np.zeros_like(t)
    m = (dt >= 0) & (dt < 12 * tau_s)
    out[m] = amp_g * np.exp(-dt[m] / tau_s) * np.sin(2 * np.pi * freq_hz * dt[m])
    return out


def vibration(t: np.ndarray, events: list, rng: np.random.Generator) -> np.ndarray:
    """Accelerometer trace [g]: one burst per (time, amplitude) event + noise, quantised."""
    v = rng.normal(0.0, VIBRATION_NOISE_G, t.size)
    for t0, amp in events:
        f = rng.uniform(3000.0, 7000.0)
        v += burst(t, t0, amp * rng.choice((-1.0, 1.0)), f, rng.uniform(2e-4, 4e-4))
        v += burst(t, t0, 0.3 * amp, rng.uniform(800.0, 1500.0), rng.uniform(5e-4, 1e-3))
    return quantise(v, VIBRATION_SPAN)
