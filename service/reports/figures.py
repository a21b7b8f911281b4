"""The condition report's figures, drawn with matplotlib (Agg) into PNG bytes.

Each function takes the plain data of ``content`` and returns one PNG; the PDF places it at a
given width. Times on trend axes are dates (UTC); curves are in ms from the first sample and
rad from closed, as the web page draws them.
"""

from __future__ import annotations

import io

import numpy as np

from service.decimation import minmax_indices
from service.display import parameter_label, parameter_short, plural, unit
from service.plots import require_matplotlib

DPI = 150  # sharp on paper at the widths used (≤ 180 mm: ≥ 1000 px), a few 100 kB per figure
WIDTH_IN = 7.0  # the figures' width [in] (the page's text width, 180 mm)
FAN_POINTS = 400  # observed points drawn in a prognosis fan (decimated min/max)

COLOURS = {"measured": "#1f4e79", "fitted": "#d9822b", "band": "#9ecae1", "value": "#1f4e79",
           "baseline": "#555555", "limit": "#c0392b", "warning": "#e6a700", "alarm": "#c0392b"}


def _figure(rows: int, cols: int, height_in: float):
    """A figure and its axes grid, made without pyplot: pyplot keeps global state and is not
    thread-safe, and the API renders reports in worker threads, several at once."""
    require_matplotlib("the condition report's figures")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(WIDTH_IN, height_in), layout="constrained")
    return fig, fig.subplots(rows, cols, squeeze=False)


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)  # a bare Figure draws with Agg
    return buf.getvalue()


def _style(ax):
    ax.grid(True, color="#dddddd", linewidth=0.6)
    ax.tick_params(labelsize=7)
    for s in ("top", "right"):
        ax.spines[s].set_visible(False)


def _naive_utc(times) -> np.ndarray:
    """Aware UTC datetimes as numpy datetime64 (UTC, as matplotlib's date axis expects)."""
    from datetime import timezone

    return np.asarray([(x.astimezone(timezone.utc) if x.tzinfo else x).replace(tzinfo=None) for x in times],
                      dtype="datetime64[ms]")


def _date_axis(ax, t) -> None:
    """Time ticks an engineer reads without an offset label: clock times within a day (the day
    in the axis title), dates within a year, months beyond."""
    import matplotlib.dates as mdates

    if len(t) == 0:
        return
    span_days = float((t.max() - t.min()) / np.timedelta64(1, "D"))
    first, last = str(t.min())[:10], str(t.max())[:10]
    if span_days < 2:
        fmt = "%H:%M"
        label = f"time (UTC) on {first}" if first == last else f"time (UTC), {first} to {last}"
    elif span_days < 370:
        fmt, label = "%m-%d", f"date (UTC), {first} to {last}"
    else:
        fmt, label = "%Y-%m", "month (UTC)"
    ax.xaxis.set_major_locator(mdates.AutoDateLocator(minticks=3, maxticks=6))
    ax.xaxis.set_major_formatter(mdates.DateFormatter(fmt))
    ax.set_xlabel(label, fontsize=7)


def curves_png(latest: dict) -> bytes | None:
    """The latest opening's and closing's travel: measured and fitted, side by side."""
    shown = [(k, v) for k, v in latest.items() if v is not None and v.curve is not None]
    if not shown:
        return None
    fig, axes = _figure(1, len(shown), 2.2)
    for ax, (kind, op) in zip(axes[0], shown):
        c = op.curve
        t_ms = np.asarray(c["t_s"]) * 1e3
        ax.plot(t_ms, c["measured_rad"], color=COLOURS["measured"], linewidth=1.0, label="measured")
        if c.get("fitted_rad") is not None:
            ax.plot(t_ms, c["fitted_rad"], color=COLOURS["fitted"], linewidth=1.0, linestyle="--", label="fitted model")
        ax.set_title(f"{'Opening' if kind == 'open' else 'Closing'} #{op.operation_id}, "
                     f"{op.occurred_at:%Y-%m-%d %H:%M} UTC", fontsize=8)
        ax.set_xlabel("time [ms]", fontsize=7)
        ax.set_ylabel("travel from closed [rad]", fontsize=7)
        ax.legend(fontsize=6, loc="best")
        _style(ax)
    return _png(fig)


def trends_png(trends: list) -> bytes | None:
    """Each fitted parameter over the operations: value, its 95 % band, the baseline and the
    breaker file's limits; alarms marked where they were raised."""
    if not trends:
        return None
    cols = 2
    rows = -(-len(trends) // cols)
    fig, axes = _figure(rows, cols, 1.75 * rows + 0.3)
    for ax in axes.flat[len(trends):]:
        ax.set_visible(False)
    for ax, tr in zip(axes.flat, trends):
        t = _naive_utc(tr.t)
        band = np.isfinite(tr.low) & np.isfinite(tr.high)
        if band.any():
            ax.fill_between(t, np.where(band, tr.low, np.nan), np.where(band, tr.high, np.nan),
                            color=COLOURS["band"], alpha=0.6, linewidth=0, label="95 % interval")
        ax.plot(t, tr.value, color=COLOURS["value"], linewidth=0.7, marker="." if len(t) < 60 else None,
                markersize=2, label="fitted value")
        if tr.baseline:
            ax.axhline(tr.baseline, color=COLOURS["baseline"], linestyle="--", linewidth=0.8, label="baseline")
        for side, value in tr.limits:
            bound = "min" if side == "falling" else "max"
            ax.axhline(value, color=COLOURS["limit"], linewidth=1.0, label=f"limit ({bound})")
        for at, level in tr.alarms:
            ax.axvline(_naive_utc([at])[0], color=COLOURS[level], linewidth=1.0, linestyle=":")
        ax.set_title(f"{parameter_label(tr.name)}, {plural(tr.count, 'fit')}", fontsize=8)
        ax.set_ylabel(f"{tr.name} [{unit(tr.name)}]", fontsize=7)
        _date_axis(ax, t)
        _style(ax)
    handles = {}
    for ax in axes.flat[:len(trends)]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    if any(tr.alarms for tr in trends):
        from matplotlib.lines import Line2D

        handles["alarm raised"] = Line2D([], [], color=COLOURS["alarm"], linewidth=1.0, linestyle=":")
    fig.legend(handles.values(), handles.keys(), loc="outside lower center", ncol=min(6, len(handles)), fontsize=7,
               frameon=False)
    return _png(fig)


def _fan_span(f: dict, limit: float | None) -> tuple[float, float]:
    """The value axis of a fan: the median path, the observed values and the limit with half their
    span as margin. A band from a short basis can be wider than any physical value (a negative
    stiffness); it is cut at the axis, not allowed to flatten what matters."""
    obs = (f.get("observed") or {}).get("value") or []
    vals = np.asarray([*f["median"], *obs, *([limit] if limit is not None else [])], float)
    vals = vals[np.isfinite(vals)]
    lo, hi = float(vals.min()), float(vals.max())
    pad = 0.5 * (hi - lo) or 0.05 * abs(hi) or 1.0
    return lo - pad, hi + pad


def fan_png(prognoses: list, limit_words: dict | None = None) -> bytes | None:
    """Each limited parameter's projected level (5/50/95 %) toward its limit(s); ``limit_words``:
    parameter -> its limit in words (ParameterLimit.words)."""
    shown = [p for p in prognoses if p.fan and p.fan.get("operations")]
    if not shown:
        return None
    fig, axes = _figure(1, len(shown), 2.3)
    for ax, p in zip(axes[0], shown):
        f = p.fan
        n = np.asarray(f["operations"], float)
        ax.fill_between(n, f["p05"], f["p95"], color=COLOURS["band"], alpha=0.6, linewidth=0, label="5–95 %")
        ax.plot(n, f["median"], color=COLOURS["value"], linewidth=1.0, label="median")
        obs = f.get("observed") or {}
        if obs.get("operations"):
            on, ov = np.asarray(obs["operations"], float), np.asarray(obs["value"], float)
            keep = minmax_indices(ov, FAN_POINTS // 2)
            ax.plot(on[keep], ov[keep], ".", color="#333333", markersize=1.5, label="fits (compensated)")
        lims = [lim["value"] for lim in (getattr(p, "limits", None) or [])] or ([p.limit] if p.limit is not None else [])
        for i, value in enumerate(lims):
            ax.axhline(value, color=COLOURS["limit"], linewidth=1.0, label="limit" if i == 0 else None)
        ax.set_ylim(*_fan_span(f, p.limit))
        if f.get("now") is not None:
            ax.axvline(f["now"], color=COLOURS["baseline"], linestyle=":", linewidth=0.8)
        ax.set_title(f"{parameter_label(p.parameter)}: limit {(limit_words or {}).get(p.parameter) or p.limit_text}",
                     fontsize=8)
        ax.set_xlabel("operations from the trend's first fit", fontsize=7)
        ax.set_ylabel(f"{parameter_short(p.parameter)}, compensated [{unit(p.parameter)}]", fontsize=7)
        ax.legend(fontsize=6, loc="best")
        _style(ax)
    return _png(fig)
