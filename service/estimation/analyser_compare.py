"""The analyser's own results beside hvcb's characteristics of the same operation.

An analyser export states its figures per travel channel (``drivers.analyser`` reads them into
``results``); hvcb's fit reports the same kinds of figure in the record's unit
(``characteristics_record``: mm, m/s, s). Where both exist they are set side by side with the
difference (hvcb − analyser). The definitions differ (an analyser's velocity is taken between
its own velocity points, hvcb's average speed between 10 % and 60 % of the stroke), so a
difference is a comparison, not an error of either.
"""

from __future__ import annotations

import math

# (label, unit, hvcb key in characteristics_record, hvcb scale to unit, analyser result names
#  tried in order) per operation; {op} is "open" or "close", {word} "opening" or "closing".
QUANTITIES = (
    ("{word} time", "ms", "operating_time_s", 1e3, ("{op}_time_ms", "{word}_time_ms")),
    ("speed", "m/s", "average_speed_m_s", 1.0, ("{op}_velocity_m_s", "{op}_datum_velocity_m_s")),
    ("overtravel", "mm", "overtravel_mm", 1.0, ("{op}_over_travel_mm",)),
    ("rebound", "mm", "rebound_mm", 1.0, ("{op}_rebound_mm",)),
)


def _number(v) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def analyser_comparison(analyser: dict | None, record: dict | None, operation: str) -> list[dict]:
    """Rows ``{quantity, unit, channel, analyser, analyser_result, hvcb, difference}``: every
    quantity of ``QUANTITIES`` that the analyser states for the fitted travel channel and hvcb
    computed. ``analyser``: the capture's ``meta["analyser"]``; ``record``: the fit's
    ``characteristics_record``. A zero from the analyser means "not computed" (the exports fill
    unmeasured results with 0) and is left out, as is a value kept as text (``∞``)."""
    if not analyser or not record:
        return []
    results = analyser.get("results") or {}
    channel = record.get("channel")
    word = "opening" if operation == "open" else "closing"
    rows = []
    for label, unit, key, scale, names in QUANTITIES:
        ours = _number(record.get(key))
        if ours is None:
            continue
        for name in (n.format(op=operation, word=word) for n in names):
            per = results.get(name)
            theirs = _number(per.get(channel) if isinstance(per, dict) else per)
            if theirs is None or theirs == 0:
                continue
            ours_u = ours * scale
            rows.append({"quantity": label.format(word=word), "unit": unit, "channel": channel,
                         "analyser": theirs, "analyser_result": name, "hvcb": ours_u,
                         "difference": ours_u - theirs})
            break
    return rows


def record_view(capture, operation: str, breaker, fit) -> dict:
    """The operation page's analyser block: the recorded channels and marked instants
    (``service.acquisition.recorded_channels.channel_plot``) and ``analyser_comparison`` rows
    (empty until the fit is done, or for a capture without analyser results)."""
    from ..acquisition.recorded_channels import channel_plot

    out = channel_plot(capture, operation, breaker.stroke)
    result = (fit.result or {}) if fit is not None and fit.status == "done" else {}
    out["analyser_comparison"] = analyser_comparison((getattr(capture, "meta", None) or {}).get("analyser"),
                                                     result.get("characteristics_record"), operation)
    return out
