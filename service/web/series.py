"""Numbers for the page's charts: pure functions, no I/O.

Times on the wire are seconds (Unix epoch for trends, from the first sample for curves); angles
stay in rad (the page converts for its axes). Display decimation keeps extremes: a vibration
shock spans a few samples and must never vanish between two plotted points.
"""

from __future__ import annotations

import json
import math
from collections import OrderedDict
from datetime import datetime
from threading import Lock

import numpy as np

from service.alarms import drift
from service.decimation import minmax_buckets, minmax_indices  # noqa: F401 (the charts' decimation)
from service.mechanics.coordinates import operation_coordinate
from service.storage.fit_curve import fit_curve

CHARACTERISTICS = (("operating_time_s", "operating time", "ms", 1e3),
                   ("average_speed_rad_s", "average speed", "rad/s", 1.0),
                   ("overtravel_rad", "overtravel", "mrad", 1e3),
                   ("rebound_rad", "rebound", "mrad", 1e3))


def epoch(t: datetime) -> float:
    return round(t.timestamp(), 3)


def finite_or_none(v, digits: int | None = None):
    if v is None:
        return None
    v = float(v)
    if not math.isfinite(v):
        return None
    return round(v, digits) if digits is not None else v


# The fleet sparklines' vertical axis spans at least ±5 % about the mean: the drift alarms' design
# step is 5 % (docs/alarms.md: 2.5 σ at the ~2 % run-to-run spread), so a 5 % step fills half the
# box while the fits' ordinary 1–2 % scatter stays a ripple and never looks like a collapse.
SPARK_MIN_SPAN_REL = 0.10


def spark_axis(values: list[float], min_span_rel: float = SPARK_MIN_SPAN_REL) -> tuple[float, float] | None:
    """The sparkline's axis (low, high) in the values' unit: their range, widened symmetrically to
    at least ``min_span_rel`` of the mean's magnitude; None with fewer than two values."""
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    if len(v) < 2:
        return None
    lo, hi = min(v), max(v)
    need = min_span_rel * abs(sum(v) / len(v))
    if hi - lo < need:
        mid = (hi + lo) / 2
        lo, hi = mid - need / 2, mid + need / 2
    return lo, hi


def sparkline(values: list[float], width: float = 120, height: float = 28, pad: float = 2,
              axis: tuple[float, float] | None = None) -> str:
    """SVG polyline points for a small trend (oldest first), on ``axis`` (low, high) when given,
    else on the values' own range."""
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    if len(v) < 2:
        return ""
    lo, hi = axis if axis is not None else (min(v), max(v))
    span = (hi - lo) or abs(hi) * 1e-3 or 1.0
    step = (width - 2 * pad) / (len(v) - 1)
    return " ".join(f"{pad + i * step:.1f},{pad + (height - 2 * pad) * (1 - (x - lo) / span):.1f}"
                    for i, x in enumerate(v))


class DriftTraces:
    """The drift statistic after every good fit, replayed with the detector the alarms use.

    The detector stores only its latest state; the trend needs the whole path, so the history is
    replayed (pure ``drift.update``) and the result kept per breaker and parameter, extended
    incrementally when new fits arrive.
    """

    def __init__(self, size: int = 64):
        self._cache: OrderedDict = OrderedDict()
        self._size = size
        self._lock = Lock()

    def trace(self, breaker_id: int, parameter: str, since: datetime | None, ops: list, times: list,
              values: list, lows: list, highs: list, settings, temps: list | None = None) -> dict:
        """ops/times/values/lows/highs: the parameter's good fits, oldest first (already filtered
        to identifiable ones after ``since``). Returns {"t", "s", "baseline", "warning", "alarm"}."""
        key = (breaker_id, parameter, since, json.dumps(settings.to_dict(), sort_keys=True))
        with self._lock:
            hit = self._cache.get(key)
        start, state, out_t, out_s = 0, drift.DriftState.new(parameter, settings), [], []
        if hit is not None:
            n, last_op, h_state, h_t, h_s = hit
            if n <= len(ops) and n > 0 and ops[n - 1] == last_op:
                start, state, out_t, out_s = n, h_state, list(h_t), list(h_s)
        for i in range(start, len(ops)):
            ci = (lows[i], highs[i]) if lows[i] is not None and highs[i] is not None else None
            obs = drift.FitObservation(operation_id=ops[i], time=times[i], value=values[i], ci95=ci,
                                       temperature=temps[i] if temps else None)
            try:
                state, _ = drift.update(state, obs, settings)
            except ValueError:  # out-of-order fit: the detector skipped it too
                continue
            out_t.append(epoch(times[i]))
            out_s.append(round(state.statistic, 4) if state.phase == "monitoring" else None)
        if ops:
            with self._lock:
                self._cache[key] = (len(ops), ops[-1], state, out_t, out_s)
                self._cache.move_to_end(key)
                while len(self._cache) > self._size:
                    self._cache.popitem(last=False)
        b = state.baseline
        return {"t": out_t, "s": out_s, "warning": settings.h_warning, "alarm": settings.h_alarm,
                "baseline": None if b is None else {"mean": b.mean, "sd": b.sd, "n": b.n},
                "collected": len(state.collected), "baseline_n": settings.baseline_n,
                "temperature_compensated": state.compensated}


def characteristics_series(rows: list[tuple]) -> dict:
    """{"open"|"close": {"t": [...], key: [... display unit]}} from (time, kind, characteristics)."""
    out: dict = {}
    for t, kind, ch in rows:
        if not ch:
            continue
        col = out.setdefault(kind, {"t": [], **{k: [] for k, *_ in CHARACTERISTICS}})
        col["t"].append(epoch(t))
        for k, _, _, scale in CHARACTERISTICS:
            v = finite_or_none(ch.get(k))
            col[k].append(None if v is None else round(v * scale, 6))
    return out


def phase_spans(kind: str, fit_t, fit_travel, window: tuple[float, float], onset_delay_s: float | None,
                breaker) -> list[dict]:
    """The physical phases of the operation [s from the first sample], from the fitted curve."""
    from service.diagnosis.phases import phase_bounds

    t = np.asarray(fit_t, float)
    y = operation_coordinate(np.asarray(fit_travel, float), kind, breaker.stroke)
    t0 = window[0] + (onset_delay_s or 0.0)
    inside = (t >= t0) & (t <= window[1])
    if inside.sum() < 3:
        return []
    tm = t[inside] - t0
    bounds = phase_bounds(kind, tm, y[inside], float(window[1] - t0), breaker)
    return [{"name": n, "t0": t0 + a, "t1": t0 + b} for n, a, b in bounds if b > a]


def operation_curves(capture, fit, breaker, *, vibration_buckets: int = 2000) -> dict:
    """Everything the operation page plots, at full resolution for the travel.

    capture: ``Capture`` (travel [rad], vibration [g]); fit: the FitRow or None.
    """
    t = capture.t
    travel = capture.travel
    out = {"t": np.round(t, 7).tolist(), "measured": np.round(travel, 6).tolist(),
           "fitted": None, "residual": None, "window": None, "noise": None, "phases": [],
           "vibration": None, "sample_rate": capture.sample_rate, "samples": int(travel.size)}
    if capture.vibration is not None:
        vt, vlo, vhi = minmax_buckets(t, capture.vibration, vibration_buckets)
        out["vibration"] = {"t": [round(v, 7) for v in vt], "min": [round(v, 3) for v in vlo],
                            "max": [round(v, 3) for v in vhi], "buckets": len(vt)}
    curve = fit_curve(fit, t, breaker)
    if curve is not None and fit.window_start_s is not None:
        ft, fv = curve
        w0, w1 = float(fit.window_start_s), float(fit.window_end_s)
        inside = (t >= max(ft[0], w0)) & (t <= min(ft[-1], w1))
        fitted = np.where(inside, np.interp(t, ft, fv), np.nan)
        resid = travel - fitted
        out["fitted"] = [None if not np.isfinite(v) else round(float(v), 6) for v in fitted]
        out["residual"] = [None if not np.isfinite(v) else round(float(v), 7) for v in resid]
        out["window"] = [w0, w1]
        band = (getattr(fit, "interval_noise", None) or {})
        # the band shows the noise the 95 % intervals stand for: the idle samples', or the residual's
        # own in motion when it is wider (service/estimation/uncertainty.py)
        out["noise"] = band.get("band_rad") or fit.noise_rad
        out["noise_basis"] = band.get("basis") or "idle samples"
        out["phases"] = phase_spans(fit.kind, ft, fv, (w0, w1), fit.onset_delay_s, breaker)
    return out
