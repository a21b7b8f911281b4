"""A second kind of travel sensor (issue 48 item 1): a linear transducer on the operating rod,
driven through a crank and a compliant coupling. A test instrument, never imported by
production code.

The realistic sensor (``sensor.py``) is a rotary transducer on the shaft through a lever. This
one is another transducer on another coupling, as fitted where the shaft end is not free:

* a **linear potentiometer** whose slider follows a crank of the shaft: it reads the crank pin's
  displacement x = R(sin(θ0 + θ) − sin θ0), θ0 the crank's angle at the closed position,
  uniform in ±``CRANK_DEG`` (20°). The instrument linearises it by its two-point calibration
  (closed and open) and a correction table that removes all but a share ``CRANK_LEFT``
  (1–3 %) of the crank's departure from the chord: the reading keeps that share of the
  sine-minus-chord form (another shape than a lever's bow, skewed by θ0);
* a **compliant coupling**: the slider's linkage is a second-order low-pass of the angle, its
  natural frequency uniform in ``COUPLING_HZ`` (500–1200 Hz), damping ratio in
  ``COUPLING_ZETA`` (0.15–0.4): the motion's own acceleration rings it, so it is struck by every
  operation in proportion to the breaker's motion, not at fixed amplitude;
* **backlash** in the coupling's pin, a play of ``PLAY_RAD`` (0.1–0.5 mrad, uniform): the
  reading lags by half the play while the motion keeps its direction (a play operator);
* an **anti-aliasing filter** of first order at ``AA_HZ`` (2–5 kHz);
* **mains pickup** at 50 Hz, amplitude uniform in ``HUM_RAD`` (0.02–0.1 mrad), random phase per
  operation;
* a **zero** per unit ±``ZERO_UNIT_RAD`` (3 mrad) plus N(0, ``ZERO_OP_RAD``²) (0.5 mrad) per
  operation, a **gain** per unit 1 ± ``GAIN_UNIT`` (2 %), and a 14-bit ADC over
  ``ADC_SPAN``.

Values are a designer's choices for a plausible installation (a slide potentiometer of 0.1 %
linearity after its table, a pin play of a few tenths of a mrad), not measured. The same seed
gives the same unit and the same reading.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.signal import bilinear, lfilter

from .sensor import adc

CRANK_DEG = 20.0
CRANK_LEFT = (0.01, 0.03)
COUPLING_HZ = (500.0, 1200.0)
COUPLING_ZETA = (0.15, 0.4)
PLAY_RAD = (0.1e-3, 0.5e-3)
AA_HZ = (2000.0, 5000.0)
HUM_RAD = (0.02e-3, 0.1e-3)
ZERO_UNIT_RAD = 3e-3
ZERO_OP_RAD = 0.5e-3
GAIN_UNIT = 0.02
ADC_BITS = 14
ADC_SPAN = (-0.2, 1.3)


@dataclass(frozen=True)
class CrankUnit:
    """One unit: crank angle at closed [rad], share of the crank's form left, coupling (f [Hz],
    ζ), play [rad], anti-aliasing corner [Hz], hum amplitude [rad], zero [rad], gain, ADC."""

    theta0: float
    left: float
    coupling_hz: float
    coupling_zeta: float
    play_rad: float
    aa_hz: float
    hum_rad: float
    zero_rad: float
    gain: float
    bits: int = ADC_BITS
    span: tuple = ADC_SPAN


def draw_unit(rng: np.random.Generator) -> CrankUnit:
    return CrankUnit(float(np.radians(rng.uniform(-CRANK_DEG, CRANK_DEG))), float(rng.uniform(*CRANK_LEFT))
                     * float(rng.choice((-1.0, 1.0))), float(rng.uniform(*COUPLING_HZ)),
                     float(rng.uniform(*COUPLING_ZETA)), float(rng.uniform(*PLAY_RAD)), float(rng.uniform(*AA_HZ)),
                     float(rng.uniform(*HUM_RAD)), float(rng.uniform(-ZERO_UNIT_RAD, ZERO_UNIT_RAD)),
                     float(1.0 + rng.uniform(-GAIN_UNIT, GAIN_UNIT)))


def crank_form(theta, theta0: float, stroke: float) -> np.ndarray:
    """The crank's departure from its chord [rad], zero at closed and open: S·(x(θ)/x(S) − θ/S),
    x(θ) = sin(θ0 + θ) − sin θ0."""
    th = np.clip(np.asarray(theta, float), 0.0, stroke)
    x = np.sin(theta0 + th) - np.sin(theta0)
    xs = np.sin(theta0 + stroke) - np.sin(theta0)
    return stroke * (x / xs - th / stroke)


def play(y, width: float) -> np.ndarray:
    """The play (backlash) operator of total ``width`` [rad]: the output follows the input only
    when the input pushes it from either side."""
    y = np.asarray(y, float)
    out = np.empty_like(y)
    h = 0.5 * width
    v = y[0] if y.size else 0.0
    for i, x in enumerate(y):
        if x > v + h:
            v = x - h
        elif x < v - h:
            v = x + h
        out[i] = v
    return out


def _lowpass2(y, fs, f, zeta):
    w = 2.0 * np.pi * f
    b, a = bilinear([w * w], [1.0, 2.0 * zeta * w, w * w], fs)
    return lfilter(b, a, y - y[0]) + y[0]


def _lowpass1(y, fs, f):
    w = 2.0 * np.pi * f
    b, a = bilinear([w], [1.0, w], fs)
    return lfilter(b, a, y - y[0]) + y[0]


def reading(y, sample_rate: float, sensor: dict, *, with_bow: bool = True) -> np.ndarray:
    """What the unit of ``sensor`` (``meta['sensor']``) reads for travel ``y`` [rad] before the
    ADC. ``with_bow`` False: without the crank's form (the oracle's detectability test)."""
    y = np.asarray(y, float)
    fs = float(sample_rate)
    S = sensor["stroke_rad"]
    x = y + (sensor["left"] * crank_form(y, sensor["theta0"], S) if with_bow else 0.0)
    x = _lowpass2(x, fs, sensor["coupling_hz"], sensor["coupling_zeta"])
    x = play(x, sensor["play_rad"])
    x = _lowpass1(x, fs, sensor["aa_hz"])
    t = np.arange(y.size) / fs
    x = sensor["gain"] * x + sensor["zero_rad"] + sensor["hum_rad"] * np.sin(2 * np.pi * 50.0 * t + sensor["hum_phase"])
    return x


def apply(capture, unit: CrankUnit, rng: np.random.Generator, *, stroke: float | None = None,
          operation: str | None = None):
    """``capture`` read through ``unit`` (one operation: its zero drift and hum phase drawn from
    ``rng``). Returns a new Capture; ``meta['sensor']`` holds what was applied."""
    y = np.asarray(capture.travel, float)
    S = float(stroke) if stroke else float(np.nanmax(y) - np.nanmin(y)) or 1.0
    sensor = {"kind": "crank", **dataclasses.asdict(unit), "span_rad": list(unit.span), "stroke_rad": S,
              "zero_rad": unit.zero_rad + float(rng.normal(0.0, ZERO_OP_RAD)),
              "hum_phase": float(rng.uniform(0.0, 2.0 * np.pi)), "operation": operation}
    sensor.pop("span")
    read = reading(y, capture.sample_rate, sensor)
    out = adc(read, unit.bits, unit.span)
    sensor["clipped"] = int(np.sum((read <= unit.span[0]) | (read >= unit.span[1])))
    meta = dict(getattr(capture, "meta", {}) or {})
    meta["sensor"] = sensor
    return dataclasses.replace(capture, travel=out, meta=meta, travel_limits=tuple(unit.span))
