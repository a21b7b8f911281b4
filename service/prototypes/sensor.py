"""A realistic travel-sensor chain for every prototype (A–E): a test instrument, never imported by
production code (issue 42 item 2).

The prototypes' own captures carry a white sensor noise and a 16-bit grid; a substation's
transducer adds what a reduced model must tolerate without naming an effect for it:

* a **zero** [rad]: per unit, uniform in ±``ZERO_UNIT_RAD`` (2 mrad: the coupling's keying), plus
  per operation N(0, ``ZERO_OP_RAD``²) (0.3 mrad: the shaft's play, the transducer's drift);
* a **gain** per unit, 1 + uniform ±``GAIN_UNIT`` (1 %: the transducer's span and the lever's
  arm ratio);
* a **lever / transducer nonlinearity** per unit: the reading of a rotary transducer driven
  through a lever (or of a linear one on a crank) departs from the angle by a smooth bow,
  δ(θ) = k·S·4u(1 − u)·(1 + c·(2u − 1)), u = θ/S the share of the stroke S (zero at both
  ends, peak k·S mid-stroke), k uniform in ±``BOW`` (0.3 %: ~3 mrad on a 1 rad stroke) and its skew c
  uniform in ±0.5;
* **torsional modes** struck at the latch (motion onset) and at the impact (end of the stroke):
  per unit 1–2 modes with frequency uniform in ``MODE_HZ`` (300–1500 Hz), damping ratio in
  ``MODE_ZETA`` (2–5 %); per strike and operation an amplitude uniform in ``MODE_AMP_RAD``
  (0.3–1 mrad) and a random sign: a·e^(−ζωt)·sin(ω_d t) from the strike on;
* the **ADC**: the reading is clipped to the channel's span and rounded to its ``bits``-bit grid.

Everything is drawn from the ``rng`` given (``numpy.random.Generator``): the same seed gives the
same unit and the same capture. The layer works on any ``drivers.capture.Capture``: it finds the
latch and the impact from the travel itself, so it needs nothing of the prototype's internals.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

ZERO_UNIT_RAD = 2e-3          # [rad] ± per unit
ZERO_OP_RAD = 0.3e-3          # [rad] sd per operation
GAIN_UNIT = 0.01              # ± per unit (relative)
BOW = 0.003                   # ± the nonlinearity's peak, share of the stroke
MODE_HZ = (300.0, 1500.0)     # [Hz] torsional modes of the drive shaft and lever
MODE_AMP_RAD = (0.3e-3, 1e-3)  # [rad] a mode's amplitude at a strike
MODE_ZETA = (0.02, 0.05)      # damping ratio
ADC_BITS = 16
ADC_SPAN = (-0.15, 1.25)      # [rad] the travel channel's range (prototype C's transducer)


@dataclass(frozen=True)
class SensorUnit:
    """One unit's transducer: zero [rad], gain, bow k and skew c of the nonlinearity, its
    torsional modes (frequency [Hz], damping ratio), the ADC (bits, span [rad])."""

    zero_rad: float
    gain: float
    bow: float
    skew: float
    modes: tuple            # ((freq_hz, zeta), ...)
    bits: int = ADC_BITS
    span: tuple = ADC_SPAN


def draw_unit(rng: np.random.Generator, *, bits: int = ADC_BITS, span: tuple = ADC_SPAN) -> SensorUnit:
    """A unit's transducer, drawn from ``rng`` (the ranges of the module docstring)."""
    zero = float(rng.uniform(-ZERO_UNIT_RAD, ZERO_UNIT_RAD))
    gain = float(1.0 + rng.uniform(-GAIN_UNIT, GAIN_UNIT))
    bow = float(rng.uniform(-BOW, BOW))
    skew = float(rng.uniform(-0.5, 0.5))
    n = int(rng.integers(1, 3))
    modes = tuple((float(rng.uniform(*MODE_HZ)), float(rng.uniform(*MODE_ZETA))) for _ in range(n))
    return SensorUnit(zero, gain, bow, skew, modes, int(bits), tuple(span))


def bow(theta: np.ndarray, unit: SensorUnit, stroke: float) -> np.ndarray:
    """The lever/transducer nonlinearity δ(θ) [rad] at ``theta`` [rad] (module docstring)."""
    u = np.clip(np.asarray(theta, float) / stroke, 0.0, 1.0)
    return unit.bow * stroke * 4.0 * u * (1.0 - u) * (1.0 + unit.skew * (2.0 * u - 1.0))


def strikes(travel: np.ndarray, sample_rate: float) -> tuple[float, float]:
    """The latch (motion onset) and the impact (end of the stroke) [s from the first sample],
    found from the travel: the first sample 2 % of the span away from the start, and the first
    at 98 % of the way to the end value."""
    y = np.asarray(travel, float)
    n = max(int(0.002 * sample_rate), 4)
    head, tail = float(np.median(y[:n])), float(np.median(y[-n:]))
    span = tail - head
    if abs(span) <= 0:
        return 0.0, 0.0
    u = (y - head) / span
    i0 = int(np.argmax(u > 0.02))
    i1 = int(np.argmax(u > 0.98))
    return i0 / sample_rate, max(i1, i0) / sample_rate


def ringing(t: np.ndarray, t0: float, freq_hz: float, zeta: float, amp: float) -> np.ndarray:
    """A struck damped mode [rad]: amp·e^(−ζωτ)·sin(ω_d τ) for τ = t − t0 ≥ 0, else 0."""
    tau = np.asarray(t, float) - t0
    w = 2.0 * np.pi * freq_hz
    wd = w * np.sqrt(max(1.0 - zeta * zeta, 0.0))
    out = amp * np.exp(-zeta * w * np.clip(tau, 0.0, None)) * np.sin(wd * np.clip(tau, 0.0, None))
    return np.where(tau >= 0.0, out, 0.0)


def adc(x: np.ndarray, bits: int, span: tuple) -> np.ndarray:
    """Clip to ``span`` [rad] and round to its ``bits``-bit grid."""
    lo, hi = span
    step = (hi - lo) / (2 ** bits - 1)
    return np.clip(lo + np.round((np.asarray(x, float) - lo) / step) * step, lo, hi)


def apply(capture, unit: SensorUnit, rng: np.random.Generator, *, stroke: float | None = None,
          operation: str | None = None):
    """``capture`` read through ``unit``'s transducer (one operation: its own zero drift and
    strike amplitudes drawn from ``rng``). ``stroke`` [rad]: the breaker's (default: the
    travel's span). The travel is measured from the closed position, so the bow is the same
    function of angle on an opening and a closing. Returns a new Capture; ``meta['sensor']``
    holds what was applied."""
    y = np.asarray(capture.travel, float)
    fs = float(capture.sample_rate)
    S = float(stroke) if stroke else float(np.nanmax(y) - np.nanmin(y)) or 1.0
    zero = unit.zero_rad + float(rng.normal(0.0, ZERO_OP_RAD))
    t_latch, t_impact = strikes(y, fs)
    applied = []
    for t0 in (t_latch, t_impact):
        for f, z in unit.modes:
            a = float(rng.uniform(*MODE_AMP_RAD)) * float(rng.choice((-1.0, 1.0)))
            applied.append({"t_s": t0, "freq_hz": f, "zeta": z, "amp_rad": a})
    sensor = {"kind": "realistic", "zero_rad": zero, "gain": unit.gain, "bow": unit.bow, "skew": unit.skew,
              "strikes": applied, "bits": unit.bits, "span_rad": list(unit.span), "stroke_rad": S,
              "operation": operation}
    read = reading(y, fs, sensor)
    out = adc(read, unit.bits, unit.span)
    meta = dict(getattr(capture, "meta", {}) or {})
    sensor["clipped"] = int(np.sum((read <= unit.span[0]) | (read >= unit.span[1])))
    meta["sensor"] = sensor
    return dataclasses.replace(capture, travel=out, meta=meta, travel_limits=tuple(unit.span))


def reading(y, sample_rate: float, sensor: dict, *, with_bow: bool = True) -> np.ndarray:
    """What the transducer of ``sensor`` (an applied capture's ``meta['sensor']``) reads for the
    travel ``y`` [rad] (before the ADC): the same zero, gain, bow and strikes. ``with_bow``
    False: the same reading without the bow (the oracle's test of whether the bow is
    detectable)."""
    y = np.asarray(y, float)
    t = np.arange(y.size) / float(sample_rate)
    unit = SensorUnit(sensor["zero_rad"], sensor["gain"], sensor["bow"] if with_bow else 0.0, sensor["skew"], ())
    read = unit.gain * (y + bow(y, unit, sensor["stroke_rad"])) + sensor["zero_rad"]
    for s in sensor["strikes"]:
        read = read + ringing(t, s["t_s"], s["freq_hz"], s["zeta"], s["amp_rad"])
    return read
