"""A trip strike and latch release in a mechanism's vibration, written blind.

Written from issue 49's text and the paper alone (Yan et al. 2026, section 2.4: the valid interval
starts at "the shock signature in the vibration signal at the completion of the trip operation"),
without reading any detector or any other prototype's vibration, so that the vibration detector is
not tuned to one generator. A test instrument: production code never imports it.

The trip sequence of a spring mechanism, as the generator models it:

1. the trip coil's armature is thrown against the trip latch: an impact that rings the mechanism's
   frame (a handful of lightly damped structural modes, a few kHz to ~20 kHz) — the *first shock*,
   at ``t_motion - latch_time``;
2. the latch rolls off its catch while the spring's load pushes it: low-level rubbing, a broadband
   noise that grows towards release;
3. the latch lets go: a second, usually weaker ring — the *release*, shortly before motion;
4. the shaft moves at ``t_motion`` (the travel's onset; the caller's own signal takes over from
   there).

Each ring is a sum of decaying sinusoids ``a_k exp(-zeta_k w_k t) sin(w_k t + phi_k)`` with a short
raised-cosine rise (an impact is not a step in acceleration). Frequencies, dampings and phases are
drawn per call, so two captures of one breaker ring alike but not identically.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TripTruth:
    """What was put into the vibration [s from the first sample; g].

    t_strike : the armature's strike on the latch (the first shock) [s]
    t_release : the latch's release [s]
    t_motion : the start of shaft motion, as given [s]
    latch_time : t_motion - t_strike [s]
    strike_peak_g, release_peak_g : the peak |acceleration| each ring adds [g]
    """

    t_strike: float
    t_release: float
    t_motion: float
    latch_time: float
    strike_peak_g: float
    release_peak_g: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def _ring(t: np.ndarray, t0: float, peak_g: float, rng: np.random.Generator,
          n_modes: int, f_lo: float, f_hi: float, zeta_lo: float, zeta_hi: float,
          rise_s: float) -> np.ndarray:
    """One impact's ring starting at t0, scaled so its largest |value| is ``peak_g`` [g]."""
    out = np.zeros_like(t)
    start = np.searchsorted(t, t0)
    if start >= t.size or peak_g <= 0:
        return out
    tau = t[start:] - t0
    # Log-uniform modal frequencies: structural modes spread over octaves, not evenly in Hz.
    f = np.exp(rng.uniform(np.log(f_lo), np.log(f_hi), n_modes))
    zeta = rng.uniform(zeta_lo, zeta_hi, n_modes)
    phase = rng.uniform(0, 2 * np.pi, n_modes)
    weight = rng.uniform(0.3, 1.0, n_modes)
    w = 2 * np.pi * f
    # Only the next ~8 decay times matter; beyond that the ring is far below any noise.
    span = min(tau.size, int(np.ceil(8.0 / (zeta.min() * w.min()) / max(t[1] - t[0], 1e-12))) + 1)
    tau = tau[:span]
    ring = np.zeros_like(tau)
    for a, wk, zk, pk in zip(weight, w, zeta, phase):
        ring += a * np.exp(-zk * wk * tau) * np.sin(wk * tau + pk)
    rise = np.clip(tau / rise_s, 0.0, 1.0)
    ring *= 0.5 - 0.5 * np.cos(np.pi * rise)
    top = np.max(np.abs(ring))
    if top > 0:
        out[start:start + span] = ring * (peak_g / top)
    return out


def add_trip(t, vibration, *, t_motion: float, latch_time: float, strike_peak_g: float,
             release_peak_g: float | None = None, release_lead: float = 0.4e-3,
             rub_rms_g: float | None = None, rng: np.random.Generator | int | None = None,
             full_scale_g: float = 1000.0) -> tuple[np.ndarray, TripTruth]:
    """The vibration with a trip strike and latch release added before the motion.

    t : sample times [s], increasing, evenly spaced
    vibration : the mechanism's acceleration without the trip [g], same length as t
    t_motion : start of shaft motion [s]
    latch_time : first shock (armature on latch) to the start of motion [s], > release_lead
    strike_peak_g : peak acceleration the strike adds [g]
    release_peak_g : peak the release adds [g]; default half the strike's
    release_lead : release to the start of motion [s] (the samples' README: about 0.4 ms)
    rub_rms_g : rms of the latch's rubbing between strike and release [g]; default 2 % of the strike
    rng : seed or generator for the modes and the rubbing
    full_scale_g : the channel's range; the sum is clipped there as an ADC would [g]

    Returns (vibration with the trip, TripTruth).
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(vibration, dtype=float).copy()
    if t.shape != v.shape:
        raise ValueError("t and vibration must have the same length")
    if not latch_time > release_lead >= 0:
        raise ValueError(f"latch_time ({latch_time * 1e3:.3f} ms) must exceed release_lead "
                         f"({release_lead * 1e3:.3f} ms)")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    release_peak_g = 0.5 * strike_peak_g if release_peak_g is None else release_peak_g
    rub_rms_g = 0.02 * strike_peak_g if rub_rms_g is None else rub_rms_g
    t_strike = t_motion - latch_time
    t_release = t_motion - release_lead
    # The armature is light and hard: higher, faster-decaying modes than the release, which
    # unloads the spring-loaded latch into the frame.
    strike = _ring(t, t_strike, strike_peak_g, rng, n_modes=5, f_lo=4e3, f_hi=20e3,
                   zeta_lo=0.02, zeta_hi=0.06, rise_s=30e-6)
    release = _ring(t, t_release, release_peak_g, rng, n_modes=4, f_lo=1.5e3, f_hi=12e3,
                    zeta_lo=0.03, zeta_hi=0.08, rise_s=60e-6)
    # Rubbing: band-limited noise growing linearly from strike to release.
    between = (t >= t_strike) & (t < t_release)
    if between.any() and rub_rms_g > 0:
        n = int(between.sum())
        noise = rng.normal(0.0, 1.0, n)
        kernel = np.ones(4) / 2.0  # a crude low-pass: the rub has little above ~30 kHz
        noise = np.convolve(noise, kernel, mode="same")
        ramp = np.linspace(0.2, 1.0, n)
        v[between] += rub_rms_g * ramp * noise / max(noise.std(), 1e-12)
    v += strike + release
    np.clip(v, -full_scale_g, full_scale_g, out=v)
    truth = TripTruth(t_strike=float(t_strike), t_release=float(t_release), t_motion=float(t_motion),
                      latch_time=float(latch_time), strike_peak_g=float(np.max(np.abs(strike), initial=0.0)),
                      release_peak_g=float(np.max(np.abs(release), initial=0.0)))
    return v, truth
