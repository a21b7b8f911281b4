"""Prototype D's measurement noise: white transducer noise, and structure-borne vibration that
rings in a few damped modes and reaches both the travel and the vibration channel.

The modes are AR(2) processes (the exact discretisation of a damped oscillator at the sample
rate) driven by the same excitation: an impulse at each mechanical shock (latch release, buffer
impact, end of travel; closing: latch, contact touch, closed) plus white forcing whose level
follows the shaft speed, so the noise grows with motion. The travel channel sees the modes'
displacement (the sensor arm moves with the structure), the vibration channel their
acceleration. Quantisation is the 16-bit COMTRADE file's own (the writer's scaling).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

MODES_HZ = (350.0, 900.0, 2300.0)  # frame, mechanism housing, pole column: each ±10 % per unit
SHOCKS = {"latch": 1.0, "buffer": 0.6, "end": 0.3, "touch": 0.5, "closed": 1.0}
MOTION_FORCING = 0.005  # white forcing per sample at peak speed, relative to the latch impulse:
#                         some tens of g of running vibration against a 300-500 g latch shock
VIBRATION_WHITE_G = 0.5  # accelerometer noise floor [g]


def draw_noise(rng: np.random.Generator) -> dict:
    """A unit's noise character: white sd [rad] 1.0–2.0 mrad, the coloured travel part's rms
    over the motion [rad] 0.5–1.5 mrad, the latch shock's peak [g] 300–500, the modes'
    frequencies [Hz], damping ratios [-] and weights [-]."""
    return {"white_sd_rad": float(rng.uniform(1.0e-3, 2.0e-3)),
            "coloured_rms_rad": float(rng.uniform(0.5e-3, 1.5e-3)),
            "latch_peak_g": float(rng.uniform(300.0, 500.0)),
            "modes_hz": [float(f * rng.uniform(0.9, 1.1)) for f in MODES_HZ],
            "damping": [float(rng.uniform(0.02, 0.05)) for _ in MODES_HZ],
            "weights": [float(w) for w in rng.uniform(0.5, 1.5, len(MODES_HZ))]}


def _mode(fs, f, zeta, force):
    """Displacement of one damped mode (AR(2)) driven by ``force`` per sample."""
    w = 2 * math.pi * f
    r = math.exp(-zeta * w / fs)
    wd = w * math.sqrt(1 - zeta * zeta) / fs
    return lfilter([1.0], [1.0, -2 * r * math.cos(wd), r * r], force)


def vibration_noise(rng: np.random.Generator, character: dict, rate: np.ndarray,
                    events_s: dict, fs: float) -> tuple[np.ndarray, np.ndarray, dict]:
    """(coloured travel noise [rad], vibration [g], description) for one capture.

    rate [rad/s] is the true shaft speed on the sampling grid; events_s the shocks' times [s].
    The travel part is scaled to the unit's coloured rms over the motion (where |rate| exceeds
    2 % of its peak); the vibration to the unit's latch-shock peak."""
    n = rate.size
    speed = np.abs(rate) / max(float(np.abs(rate).max()), 1e-12)
    force = MOTION_FORCING * speed * rng.standard_normal(n)
    for name, t_ev in events_s.items():
        k = round(t_ev * fs)
        if 0 <= k < n:
            force[k] += SHOCKS[name] * rng.uniform(0.7, 1.3)
    disp = np.zeros(n)
    acc = np.zeros(n)
    latch = round(events_s["latch"] * fs)
    for f, zeta, weight in zip(character["modes_hz"], character["damping"], character["weights"]):
        q = _mode(fs, f, zeta, force)
        disp += weight * q
        acc -= weight * (2 * math.pi * f) ** 2 * q
    moving = speed > 0.02
    rms = float(np.sqrt(np.mean(disp[moving] ** 2))) if moving.any() else 0.0
    travel_noise = disp * (character["coloured_rms_rad"] / rms) if rms > 0 else disp
    window = acc[latch:latch + int(2e-3 * fs)]
    peak = float(np.abs(window).max()) if window.size else float(np.abs(acc).max())
    vibration = acc * (character["latch_peak_g"] / peak) + VIBRATION_WHITE_G * rng.standard_normal(n)
    description = {
        "kind": "damped structural modes (AR(2) each) driven by shocks and speed-proportional "
                "white forcing; the travel sees their displacement, the vibration channel "
                "their acceleration",
        "modes_hz": character["modes_hz"], "damping_ratio": character["damping"],
        "rms_rad": float(np.sqrt(np.mean(travel_noise[moving] ** 2))) if moving.any() else 0.0,
        "rms_rad_record": float(np.sqrt(np.mean(travel_noise ** 2))),
        "shocks": sorted(events_s)}
    return travel_noise, vibration, description
