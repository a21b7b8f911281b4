"""The alarm page's evidence charts, drawn as SVG on the server (no script needed to read them):
the watched value as dots with its expected level and ±2σ band, and beneath it, on its own
scale, the drift statistic (CUSUM) against its thresholds. Each chart has its axes, ticks with
values and units, and axis labels; the temperature, where known, has an axis of its own.

Pure: the evidence series in (service.jobs.alarm_actions.evidence), coordinates and labels out.
"""

from __future__ import annotations

import math

W, H = 900.0, 220.0                 # the SVG's box [px]; drawn about this wide on a desktop
LEFT, RIGHT, TOP, BOTTOM = 62.0, 46.0, 8.0, 34.0   # margins for tick labels and axis titles [px]
TICKS = 5                           # at most about this many ticks per axis


def nice_ticks(lo: float, hi: float, n: int = TICKS) -> list[float]:
    """Round tick values covering [lo, hi]: steps of 1, 2, 2.5 or 5 times a power of ten (the usual
    choice of plotting libraries, e.g. Heckbert's 'nice numbers', Graphics Gems 1990)."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo] if math.isfinite(lo) else []
    raw = (hi - lo) / max(n - 1, 1)
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step - 1e-9) * step
    out, v = [], first
    while v <= hi + 1e-9 * step:
        out.append(round(v, 12))
        v += step
    return out


def tick_labels(ticks: list[float]) -> list[str]:
    """Tick values with as many decimals as their step needs ("−40", "5", "2.5"), a minus sign,
    thousands grouped from 10 000 on."""
    if not ticks:
        return []
    step = min((b - a for a, b in zip(ticks, ticks[1:])), default=abs(ticks[0]) or 1.0)
    decimals = next((d for d in range(7) if abs(round(step, d) - step) <= 1e-9 * step), 6) if step > 0 else 0
    out = []
    for t in ticks:
        text = f"{t:,.{decimals}f}" if abs(t) >= 1e4 else f"{t:.{decimals}f}"
        out.append("0" if float(text.replace(",", "")) == 0 else text.replace("-", "−"))
    return out


def _finite(values) -> list[float]:
    return [v for v in values if v is not None and math.isfinite(v)]


class _Axis:
    """A linear map from data to pixels, with its ticks."""

    def __init__(self, values, p0: float, p1: float, lo=None, hi=None):
        got = _finite(values)
        lo = min(got) if lo is None and got else (0.0 if lo is None else lo)
        hi = max(got) if hi is None and got else (1.0 if hi is None else hi)
        if hi <= lo:
            pad = abs(hi) * 1e-3 or 1.0
            lo, hi = lo - pad, hi + pad
        self.lo, self.hi, self.p0, self.p1 = lo, hi, p0, p1
        self.ticks = [t for t in nice_ticks(lo, hi) if lo <= t <= hi]

    def __call__(self, v: float) -> float:
        return self.p0 + (self.p1 - self.p0) * (v - self.lo) / (self.hi - self.lo)


def _polylines(xs, ys, f) -> list[str]:
    """SVG polyline points, broken where a value is missing."""
    parts, cur = [], []
    for x, y in zip(xs, ys):
        if y is None or not math.isfinite(y):
            if cur:
                parts.append(" ".join(cur))
            cur = []
        else:
            cur.append(f"{x:.1f},{f(y):.1f}")
    if cur:
        parts.append(" ".join(cur))
    return parts


def _x_axis(n: int) -> tuple[list[float], list[tuple[float, str]]]:
    """x of each fit (oldest left) and ticks counted back from the latest fit (0 = latest)."""
    fx = _Axis([-(n - 1), 0], LEFT, W - RIGHT, lo=-(max(n - 1, 1)), hi=0.0)
    xs = [fx(i - (n - 1)) for i in range(n)]
    values = [t for t in nice_ticks(-(n - 1), 0) if t >= -(n - 1)]
    ticks = [(fx(t), label if t else "latest") for t, label in zip(values, tick_labels(values))]
    return xs, ticks


def evidence_charts(ev: dict, unit: str) -> dict:
    """The two charts of one watched parameter's evidence, or {} with no fit yet.

    ev : the evidence (``series``: value, expected, band_low, band_high, statistic, temperature_c,
         one entry per good fit, oldest first; ``thresholds``: warning, alarm [σ])
    unit : the parameter's unit, for the value axis
    """
    s = ev["series"]
    n = len(s["value"])
    if n == 0:
        return {}
    xs, xticks = _x_axis(n)
    bottom = H - BOTTOM
    fv = _Axis(s["value"] + _finite(s["band_low"]) + _finite(s["band_high"]), bottom, TOP)
    th = ev["thresholds"]
    fs = _Axis(s["statistic"], bottom, TOP, lo=0.0,
               hi=max([th["alarm"] * 1.2] + _finite(s["statistic"])))
    temps = _finite(s["temperature_c"])
    ft = _Axis(temps, bottom, TOP) if temps else None
    dots = [(x, fv(v)) for x, v in zip(xs, s["value"]) if v is not None and math.isfinite(v)]
    value = {"dots": [f"{x:.1f},{y:.1f}" for x, y in dots],
             "expected": _polylines(xs, s["expected"], fv),
             "band_low": _polylines(xs, s["band_low"], fv), "band_high": _polylines(xs, s["band_high"], fv),
             "temperature": _polylines(xs, s["temperature_c"], ft) if ft else [],
             "yticks": list(zip(map(fv, fv.ticks), tick_labels(fv.ticks))),
             "tticks": list(zip(map(ft, ft.ticks), tick_labels(ft.ticks))) if ft else [],
             "ylabel": unit}
    cusum = {"line": _polylines(xs, s["statistic"], fs),
             "warning_y": fs(th["warning"]), "alarm_y": fs(th["alarm"]),
             "yticks": list(zip(map(fs, fs.ticks), tick_labels(fs.ticks))), "ylabel": "CUSUM [σ]"}
    return {"w": W, "h": H, "left": LEFT, "right": W - RIGHT, "top": TOP, "bottom": bottom, "n": n,
            "xticks": xticks, "xlabel": "fits before the latest (oldest left)", "value": value, "cusum": cusum,
            "has_temperature": ft is not None}
