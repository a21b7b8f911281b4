"""The coil currents' characteristic values, as breaker analysers report them (the timing tests of
IEC 62271-100's mechanical characteristics; the CIBANO 500's and TM1800's coil-current analysis):
for each energisation of a trip or close coil, the peak current, the armature's dip (the local
minimum where the moving armature stops against the latch and its back-EMF vanishes) and the time
to the current's end (the auxiliary contact breaking the coil circuit), from the energisation.

Method, on the current with a 1 ms moving average (the coil's own time constant is several ms,
so the average keeps its shape and removes the recorder's noise):
- the noise floor: the rest level and its robust spread before any energisation;
- an energisation: a span above 10 % of the record's largest coil current and 10σ of the noise,
  its start where the current leaves the rest level (3σ), gaps shorter than 2 ms bridged; a span
  no longer than the 1 ms average itself is a one-sample spike, not an energisation;
- the peak, as the analyser reads it (``peak_current_a``): the span's largest raw sample (on 38
  real exports with the analyser's own results, its coil peak is the column's raw maximum; the
  header states one number per coil, its largest pulse's). The largest averaged current beside it
  (``peak_current_smoothed_a``) is what the coil's L/R rise reaches without the recorder's noise
  or a one-sample spike;
- the armature dip: the first local minimum after the first local maximum whose rise back is
  at least ``DIP_RISE`` of the peak and 3σ of the noise; None with the reason when the current
  rises straight to its plateau;
- the current's end: where the current falls for good below 10 % of the span's peak; None with
  the reason when the record ends while it still flows.

Pure: arrays in, a list of dicts out.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import uniform_filter1d

SMOOTH_S = 1e-3
"""The average the peak and the dip are read on [s]."""
EDGE_S = 0.2e-3
"""The shorter average the energisation and the current's end are timed on [s]: the 1 ms one
would move both edges by half a millisecond."""
ON_FRACTION = 0.10
ON_SIGMA = 10.0
START_SIGMA = 3.0
MERGE_GAP_S = 2e-3
DIP_RISE = 0.03
"""A dip counts when the current rises back by this fraction of the peak after it [-]."""
MIN_CURRENT_A = 0.05
"""A coil whose largest current is below this is not energised (an unwired or idle channel) [A]."""
PEAK_TOLERANCE = 0.03
"""The issue's acceptance: hvcb's peak within 3 % of the analyser's own."""


NO_STATEMENT = ("", "NA", "N/A", "-", "--")
"""Header words that state no value."""


def stated_peak(value, channel: str) -> tuple[float | None, str | None]:
    """The analyser header's coil peak as a usable number [A], or None with the reason in words
    (a zero is no statement; an infinity or a non-number is refused, issue 57)."""
    if isinstance(value, str):  # the header's words: "NA" states nothing; "inf", "∞", "NaN" are no current
        word = value.strip()
        if word.upper() in NO_STATEMENT:
            return None, None
        try:
            value = float(word.replace("∞", "inf"))
        except ValueError:
            return None, (f"the export's header states {word!r} as the coil {channel}'s peak: not a number, "
                          "so it is not compared")
    if value is None or isinstance(value, bool) or not isinstance(value, (int, float)):
        return None, None
    if not math.isfinite(value):
        return None, (f"the export's header states {value!r} A as the coil {channel}'s peak: not a current, "
                      "so it is not compared")
    if value <= 0:
        return None, None
    return float(value), None


def coil_results(name: str, current, sample_rate: float, *, analyser_peak_a: float | None = None) -> list[dict]:
    """Each energisation of one coil channel: ``{channel, pulse, energised_s, peak_current_a,
    peak_current_smoothed_a, armature_dip_s, current_end_s}`` (currents [A]; times from the
    energisation [s], ``energised_s`` from the record's first sample), a ``*_reason`` beside a
    time that is None, and, on the coil's largest pulse where the analyser's header states the
    coil's peak, ``analyser_peak_a``, ``peak_difference_rel`` and ``note``. A header peak that is
    not a finite positive current is not compared: ``analyser_peak_reason`` says why.

    An empty list: the coil was not energised in this record.
    """
    analyser_peak_a, peak_reason = stated_peak(analyser_peak_a, name)
    x = np.asarray(current, dtype=float)
    if x.size < 16:
        return []
    fs = float(sample_rate) if isinstance(sample_rate, (int, float)) else float("nan")
    if not np.isfinite(fs) or fs <= 0:
        fin = x[np.isfinite(x)]  # an over-range ∞ is no current reading (issue 57: it reached the JSON)
        top = float(fin.max()) if fin.size else 0.0
        if top < MIN_CURRENT_A:
            return []
        why = "the record states no sample rate (a bare export): give it (hvcb inspect --rate) to time the coil"
        row = {"channel": name, "pulse": 0, "energised_s": None, "peak_current_a": round(top, 4),
               "peak_current_smoothed_a": None,
               "peak_current_smoothed_reason": "the record states no sample rate, so no 1 ms average",
               "armature_dip_s": None, "armature_dip_reason": why, "current_end_s": None, "current_end_reason": why}
        _compare(row, analyser_peak_a, peak_reason)
        return [row]
    ok = np.isfinite(x)
    if not ok.any():
        return []
    x = np.where(ok, x, 0.0)
    n_s = max(1, int(round(SMOOTH_S * fs)))
    s = uniform_filter1d(x, n_s, mode="nearest")
    edge = uniform_filter1d(x, max(1, int(round(EDGE_S * fs))), mode="nearest")
    top = float(np.max(s))
    if top < MIN_CURRENT_A:
        return []
    rest = s[s < ON_FRACTION * top]
    base = float(np.median(rest)) if rest.size else 0.0
    sigma = max(float(1.4826 * np.median(np.abs(rest - base))) if rest.size else 0.0, 1e-6)
    on = s > max(ON_FRACTION * top, base + ON_SIGMA * sigma)
    # a span no longer than the average's own width is one sample's doing (a spike), not a pulse
    spans = [(a, b) for a, b in _spans(on, int(round(MERGE_GAP_S * fs))) if b - a > n_s]
    out = []
    for k, (i0, i1) in enumerate(spans):
        # the start: back from the span to where the current left its rest level
        j = i0
        while j > 0 and edge[j - 1] > base + START_SIGMA * sigma:
            j -= 1
        seg = s[j:i1]
        peak = float(np.max(seg))
        raw = float(np.max(x[j:i1]))  # the analyser's reading: the largest sample, unaveraged
        row = {"channel": name, "pulse": k, "energised_s": j / fs, "peak_current_a": round(raw, 4),
               "peak_current_smoothed_a": round(peak, 4)}
        row.update(_dip(seg, peak, sigma, fs))
        row.update(_end(edge, j, i1, peak, fs))
        out.append(row)
    if out:  # the header's one number per coil is its largest pulse's
        _compare(max(out, key=lambda r: r["peak_current_a"]), analyser_peak_a, peak_reason)
    return out


def _compare(row: dict, analyser_peak_a: float | None, reason: str | None) -> None:
    if reason:
        row["analyser_peak_reason"] = reason
    if analyser_peak_a is None:
        return
    diff = (row["peak_current_a"] - analyser_peak_a) / analyser_peak_a
    row.update(analyser_peak_a=analyser_peak_a, peak_difference_rel=round(diff, 4),
               note=("within 3 % of the analyser's own peak" if abs(diff) <= PEAK_TOLERANCE else
                     f"{diff:+.1%} from the analyser's own peak (both are the largest raw sample of the "
                     "coil's largest pulse: the export's current column and its header disagree)"))


def _spans(mask: np.ndarray, gap: int) -> list[tuple[int, int]]:
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > gap + 1)
    starts = np.r_[idx[0], idx[breaks + 1]]
    ends = np.r_[idx[breaks] + 1, idx[-1] + 1]
    return list(zip(starts.tolist(), ends.tolist()))


def _dip(seg: np.ndarray, peak: float, sigma: float, fs: float) -> dict:
    rise = max(DIP_RISE * peak, 3.0 * sigma)
    falls = np.flatnonzero(np.diff(seg) < 0)
    if falls.size:
        i_max = int(falls[0])  # the first local maximum: the rise stops
        after = seg[i_max:]
        run_min = np.minimum.accumulate(after)
        back = np.flatnonzero(after - run_min >= rise)  # the current rises again from a minimum
        if back.size and after[0] - run_min[back[0]] >= rise:
            i_min = i_max + int(np.argmin(after[: back[0] + 1]))
            return {"armature_dip_s": i_min / fs, "armature_dip_a": round(float(seg[i_min]), 4)}
    return {"armature_dip_s": None,
            "armature_dip_reason": "no armature dip: the current rises to its plateau without the local minimum a "
                                   "moving armature makes (the armature's motion is not seen in the current)"}


def _end(s: np.ndarray, j: int, i1: int, peak: float, fs: float) -> dict:
    below = s[i1:] < ON_FRACTION * peak
    if i1 >= s.size or not below.size:
        return {"current_end_s": None,
                "current_end_reason": "the current still flows at the end of the record: its end is not recorded"}
    # where the averaged current falls through 10 % of the peak, read on the raw-rate grid
    k = i1
    while k > j and s[k - 1] < ON_FRACTION * peak:
        k -= 1
    return {"current_end_s": (k - j) / fs}


def record_coils(capture) -> list[dict]:
    """Every energised coil of a ``drivers.capture.Capture`` (its ``coil_current`` channels), with the
    analyser's own peak from the export's header where it states one (a zero is no statement)."""
    results = ((capture.meta or {}).get("analyser") or {}).get("results") or {}
    stated = results.get("coil_current_peak_a") or {}
    out = []
    for ch in capture.aux_of("coil_current"):
        peak = stated.get(ch.name) if isinstance(stated, dict) else None
        out += coil_results(ch.name, ch.data, capture.sample_rate, analyser_peak_a=peak)
    return out
