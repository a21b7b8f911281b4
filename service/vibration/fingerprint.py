"""The breaker's own vibration fingerprint, and each operation's shift from it.

The fingerprint is learnt from the breaker's first healthy operations of one kind (or its
commissioning pair): each named event's expected time and peak with their spread, the latch time's,
and the band-limited envelope's mean and spread (in dB, on a grid relative to the start of motion).
This is the reference-pattern comparison of continuous vibration monitoring (Runde et al., IEEE
TPWRD 1996; Hoidalen & Runde, "Continuous monitoring of circuit breakers using vibration
analysis", IEEE TPWRD 20(4) 2005, who compare each pattern with the breaker's references for
timing and amplitude deviations). The timing shift of the whole pattern is taken by envelope
cross-correlation (the lag that maximises the normalised cross-correlation of the log envelopes,
refined by a parabola through the peak) rather than their dynamic time warping: one lag per
operation is what the drift detector watches, and the event table gives the per-event shifts a
warping path would.

Stage contract (scikit-learn's): :class:`Fingerprint` stores its settings; :meth:`Fingerprint.fit`
learns ``events_``, ``latch_``, ``envelope_`` and ``count_``; :meth:`Fingerprint.shift` scores one
operation. Pure: no I/O.
"""

from __future__ import annotations

import warnings

import numpy as np

from .events import band

ENVELOPE_SPAN_S = (-12e-3, 70e-3)
"""Envelope grid relative to the start of motion [s]: the latch search span, then an opening's or
closing's whole stroke (the reference breaker's take 57 and 36 ms)."""
ENVELOPE_STEP_S = 0.25e-3
"""Envelope resolution [s]: one short-time-energy window (events.STE_WINDOW_S)."""
MAX_LAG_S = 3e-3
"""Largest whole-pattern shift searched [s]."""
MIN_OPERATIONS = 3
"""Healthy operations needed before a fingerprint is learnt."""
TIME_SD_FLOOR_S = 0.05e-3
"""Smallest spread of an event's time [s]: the onset picker's own scatter on strong shocks."""
PEAK_SD_FLOOR_REL = 0.10
"""Smallest spread of an event's peak, relative to it [-]."""
SEEN_FRACTION = 0.8
"""An event is part of the fingerprint when this fraction of its operations show it."""


def _four_digits(v: np.ndarray) -> np.ndarray:
    """``v`` rounded to 4 significant digits (what the stored envelope keeps)."""
    v = np.asarray(v, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        exp = np.where(v != 0, np.floor(np.log10(np.abs(v))), 0.0)
    scale = 10.0 ** (3 - exp)
    return np.round(v * scale) / scale


def envelope(vibration, sample_rate: float, t_motion_s: float, *, banded: np.ndarray | None = None) -> dict | None:
    """The band-limited rms envelope [g] on the fingerprint's grid (None outside the capture).

    Returns ``{"t0_s", "dt_s", "g"}``: the first block's start relative to the motion [s], the
    block length [s] and each block's rms [g]; None when there is no usable channel. ``banded``:
    the channel already band-passed (``events.band``), when the caller has it.
    """
    if vibration is None:
        return None
    x = np.asarray(vibration, dtype=float)
    fs = float(sample_rate)
    if x.size < 64 or not np.all(np.isfinite(x)) or np.ptp(x) == 0:
        return None
    y = band(x, fs) if banded is None else np.asarray(banded, dtype=float)
    step = max(1, int(round(ENVELOPE_STEP_S * fs)))
    i0 = int(round((t_motion_s + ENVELOPE_SPAN_S[0]) * fs))
    blocks = int(round((ENVELOPE_SPAN_S[1] - ENVELOPE_SPAN_S[0]) * fs / step))
    # each block's rms at once; a block that reaches outside the capture is None
    starts = i0 + step * np.arange(blocks)
    inside = (starts >= 0) & (starts + step <= y.size)
    rms = np.full(blocks, np.nan)
    if inside.any():
        first, last = int(np.argmax(inside)), int(blocks - 1 - np.argmax(inside[::-1]))
        seg = y[starts[first]: starts[last] + step] ** 2
        rms[first:last + 1] = np.sqrt(seg.reshape(last - first + 1, step).mean(axis=1))
    g = [v if ok else None for ok, v in zip(inside.tolist(), _four_digits(rms).tolist())]
    return {"t0_s": (i0 - t_motion_s * fs) / fs, "dt_s": step / fs, "g": g}


def _db(env: dict) -> np.ndarray:
    return np.array([np.nan if v is None else 20.0 * np.log10(max(v, 1e-6)) for v in env["g"]])


class Fingerprint:
    """A breaker's healthy vibration pattern for one operation kind.

    Parameters
    ----------
    operation : {"open", "close"}
    min_operations : int
        Healthy operations needed to learn it.
    """

    def __init__(self, operation: str, min_operations: int = MIN_OPERATIONS):
        self.operation = operation
        self.min_operations = min_operations

    def fit(self, characteristics: list[dict], operation_ids: list | None = None) -> "Fingerprint":
        """Learn from the characteristics of healthy operations (each with ``vibration_events``,
        ``latch_time_s`` and optionally ``vibration_envelope``).

        Raises
        ------
        ValueError
            Fewer than ``min_operations`` operations with a read vibration.
        """
        usable = [c for c in characteristics if c and c.get("vibration_events")]
        if len(usable) < self.min_operations:
            raise ValueError(f"a vibration fingerprint needs {self.min_operations} healthy operations with a "
                             f"read vibration channel; {len(usable)} given")
        names = sorted({e["name"] for c in usable for e in c["vibration_events"] if e["name"] != "impact"})
        self.events_ = {}
        for name in names:
            ts = [e["t_s"] for c in usable for e in c["vibration_events"][:] if e["name"] == name]
            peaks = [e["peak_g"] for c in usable for e in c["vibration_events"] if e["name"] == name]
            seen = len(ts) / len(usable)
            if seen < SEEN_FRACTION:
                continue
            t_med, p_med = float(np.median(ts)), float(np.median(peaks))
            self.events_[name] = {"t_s": t_med, "t_sd_s": max(_robust_sd(ts), TIME_SD_FLOOR_S),
                                  "peak_g": p_med, "peak_sd_g": max(_robust_sd(peaks), PEAK_SD_FLOOR_REL * p_med),
                                  "seen": seen}
        latch = [c["latch_time_s"] for c in usable if c.get("latch_time_s") is not None]
        self.latch_ = ({"mean_s": float(np.median(latch)), "sd_s": max(_robust_sd(latch), TIME_SD_FLOOR_S),
                        "n": len(latch)} if latch else None)
        envs = [c["vibration_envelope"] for c in usable if c.get("vibration_envelope")]
        self.envelope_ = None
        if len(envs) >= self.min_operations and len({len(e["g"]) for e in envs}) == 1:
            db = np.vstack([_db(e) for e in envs])
            with np.errstate(all="ignore"), warnings.catch_warnings():
                # a block outside every capture is all NaN, one inside a single capture has no sd
                warnings.simplefilter("ignore", RuntimeWarning)
                mean, sd = np.nanmean(db, axis=0), np.nanstd(db, axis=0, ddof=1)
            self.envelope_ = {"t0_s": envs[0]["t0_s"], "dt_s": envs[0]["dt_s"],
                              "mean_db": [None if not np.isfinite(v) else round(float(v), 2) for v in mean],
                              "sd_db": [None if not np.isfinite(v) else round(float(max(v, 1.0)), 2) for v in sd]}
        self.count_ = len(usable)
        self.operation_ids_ = list(operation_ids or [])
        return self

    def to_dict(self) -> dict:
        return {"operation": self.operation, "count": self.count_, "operation_ids": self.operation_ids_,
                "events": self.events_, "latch": self.latch_, "envelope": self.envelope_}

    def shift(self, characteristics: dict) -> dict:
        """One operation against the fingerprint.

        Returns ``{"events": {name: {"shift_s", "z_time", "peak_ratio"}}, "latch_shift_s",
        "latch_z", "envelope_lag_s", "envelope_correlation", "outside_band_fraction",
        "strike_not_seen"}`` (a value None where it cannot be taken). ``strike_not_seen`` is the
        reason in words when this operation's first shock sits where the fingerprint's latch
        release is: the strike was missed, so its latch time must not be read as a time.
        """
        evs = {e["name"]: e for e in characteristics.get("vibration_events") or []}
        out_events = {}
        for name, ref in self.events_.items():
            e = evs.get(name)
            if e is None:
                continue
            out_events[name] = {"shift_s": e["t_s"] - ref["t_s"], "z_time": (e["t_s"] - ref["t_s"]) / ref["t_sd_s"],
                                "peak_ratio": e["peak_g"] / ref["peak_g"] if ref["peak_g"] > 0 else None}
        latch = characteristics.get("latch_time_s")
        out = {"events": out_events, "latch_shift_s": None, "latch_z": None, "envelope_lag_s": None,
               "envelope_correlation": None, "outside_band_fraction": None, "strike_not_seen": None}
        if latch is not None and self.latch_ is not None:
            out["latch_shift_s"] = latch - self.latch_["mean_s"]
            out["latch_z"] = out["latch_shift_s"] / self.latch_["sd_s"]
        rel = self.events_.get("latch_release")
        first = evs.get("first_shock")
        if rel is not None and first is not None and "latch_release" not in evs \
                and abs(first["t_s"] - rel["t_s"]) <= max(3 * rel["t_sd_s"], 0.15e-3):
            out["strike_not_seen"] = (f"the first shock ({-first['t_s'] * 1e3:.2f} ms before motion) is where this "
                                      f"breaker's latch release is ({-rel['t_s'] * 1e3:.2f} ms): the trip strike "
                                      "was not seen, so no latch time is read")
        env = characteristics.get("vibration_envelope")
        if env and self.envelope_ and len(env["g"]) == len(self.envelope_["mean_db"]):
            lag, corr = envelope_lag(_db(env), np.array([np.nan if v is None else v for v in self.envelope_["mean_db"]],
                                                        dtype=float), env["dt_s"])
            out["envelope_lag_s"], out["envelope_correlation"] = lag, corr
            mean = np.array([np.nan if v is None else v for v in self.envelope_["mean_db"]], dtype=float)
            sd = np.array([np.nan if v is None else v for v in self.envelope_["sd_db"]], dtype=float)
            x = _db(env)
            ok = np.isfinite(x) & np.isfinite(mean) & np.isfinite(sd)
            if ok.any():
                out["outside_band_fraction"] = float(np.mean(np.abs(x[ok] - mean[ok]) > 3 * sd[ok]))
        return out


def envelope_lag(x_db: np.ndarray, ref_db: np.ndarray, dt_s: float, max_lag_s: float = MAX_LAG_S):
    """(lag [s], correlation) of the normalised cross-correlation of two log envelopes; a positive
    lag means ``x`` comes later than ``ref``."""
    ok = np.isfinite(x_db) & np.isfinite(ref_db)
    if ok.sum() < 16:
        return None, None
    x = np.where(ok, x_db - np.nanmean(x_db[ok]), 0.0)
    r = np.where(ok, ref_db - np.nanmean(ref_db[ok]), 0.0)
    m = int(round(max_lag_s / dt_s))
    lags = np.arange(-m, m + 1)
    c = []
    for k in lags:
        a, b = (x[k:], r[:r.size - k]) if k >= 0 else (x[:k], r[-k:])
        den = np.sqrt(np.dot(a, a) * np.dot(b, b))
        c.append(float(np.dot(a, b) / den) if den > 0 else 0.0)
    c = np.array(c)
    j = int(np.argmax(c))
    frac = 0.0
    if 0 < j < c.size - 1:
        den = c[j - 1] - 2 * c[j] + c[j + 1]
        frac = 0.5 * (c[j - 1] - c[j + 1]) / den if den < 0 else 0.0
    return float((lags[j] + frac) * dt_s), float(c[j])


def _robust_sd(v) -> float:
    v = np.asarray(v, dtype=float)
    if v.size < 2:
        return 0.0
    return float(1.4826 * np.median(np.abs(v - np.median(v))))
