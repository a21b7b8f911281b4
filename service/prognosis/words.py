"""A prognosis in words a maintenance planner reads: the parameter's name, values with their
units, the limit as a value and as a change from the baseline, whole openings and dates.

Pure: the breaker page's card, the fan chart's legend and the fleet's column all take their
text from here (through the JSON of service/jobs/prognosis.py), so they cannot disagree.
"""

from __future__ import annotations

import math
from datetime import datetime

from service.display import parameter_label
from service.findings import action
from service.mechanics.nomenclature import UNITS

# Fitted opening parameters and the opening's vibration readings (the trip latch's time, the
# buffer's ratio: service.storage.crud_vibration.WATCHABLE) come from openings, closing ones from closings.
OPENING = {"AO", "BO", "DO", "EO", "latch_time_s", "buffer_ratio"}


def name(parameter: str) -> str:
    """The parameter in words with its code: "buffer damping (DO)"."""
    return parameter_label(parameter)


def value(x: float, parameter: str) -> str:
    """A parameter's value to 3 significant figures (whole numbers from 1 000 on), with its unit."""
    unit = UNITS.get(parameter, "")
    if not math.isfinite(x):
        return "–"
    if unit == "s":  # a time (the trip latch's) reads in ms, as on the alarm pages
        x, unit = x * 1e3, "ms"
    digits = 0 if abs(x) >= 1000 or x == 0 else max(0, 2 - int(math.floor(math.log10(abs(x)))))
    text = f"{x:,.{digits}f}".replace("-", "−")
    return f"{text} {unit}".strip() if unit not in ("", "–", "1") else text


def operations(n: float, parameter: str) -> str:
    """Whole operations, with their kind: '1 opening', '1,204 openings'."""
    k = int(round(n))
    kind = "opening" if parameter in OPENING else "closing"
    return f"{k:,} {kind}{'' if k == 1 else 's'}"


def date(d) -> str:
    if isinstance(d, str):
        d = datetime.fromisoformat(d)
    return d.strftime("%Y-%m-%d")


def change(limit_value: float, baseline: float) -> str:
    """'25 % below' / '10 % above' the baseline."""
    rel = (limit_value - baseline) / baseline * 100.0
    return f"{abs(rel):.3g} % {'below' if rel < 0 else 'above'}"


def limits_text(p, parameter: str) -> str:
    """The limit(s) as values and as changes from the baseline."""
    lims = [lim["value"] for lim in p.get("limits") or []] or ([p["limit"]] if p.get("limit") is not None else [])
    base = p.get("baseline")
    if not lims:
        return f"limit {p.get('limit_text', '')}"
    if len(lims) == 1:
        tail = f", {change(lims[0], base)} its baseline of {value(base, parameter)}" if base else ""
        return f"limit {value(lims[0], parameter)}{tail}"
    lo, hi = sorted(lims)
    tail = (f", {change(lo, base).split()[0]} % below and {change(hi, base).split()[0]} % above its baseline of "
            f"{value(base, parameter)}") if base else ""
    return f"limits {value(lo, parameter)} and {value(hi, parameter)}{tail}"


def horizon_text(p) -> str:
    if p.get("horizon_years"):
        return f"{p['horizon_years']:g} years"
    return operations(p.get("horizon_operations") or 0, p["parameter"])


def _lead(now: str, lim: str) -> str:
    """"Trend level …; limits …" as a sentence's start; the limits alone without a trend level."""
    text = f"{now}; {lim}" if now else lim
    return text[:1].upper() + text[1:]


def summary(p: dict) -> str:
    """The card's sentence(s) for one prognosis (``as_json`` form)."""
    par = p["parameter"]
    who = name(par)
    who_cap = who[0].upper() + who[1:]
    # "now" is the latest fit everywhere (the alarm line, the fleet); the prognosis speaks of its trend
    now = f"trend level {value(p['current'], par)}" if p.get("current") is not None else ""
    if p.get("limit") is None and p["status"] == "no trend":
        return f"{who_cap}: no prognosis yet: {p['reason']}."
    lim = limits_text(p, par)
    if p["status"] == "crossed":
        return f"{who_cap} crossed its limit: {now}; {lim}. {action(par)}"
    q, d = p.get("operations_to_limit"), p.get("date_to_limit")
    if p["status"] == "no trend":
        early = ""
        if q and q.get("p05") is not None:
            when = f", {date(d['p05'])}" if d and d.get("p05") else ""
            early = f" At the earliest (5 %): in {operations(q['p05'], par)}{when}."
        # without a trend level yet (every fit since a logged repair left out), the limits lead
        lead = f"{now}; {lim}" if now else lim
        return (f"{who_cap}: no trend. {lead[:1].upper() + lead[1:]}. The slope's 90 % interval holds "
                f"zero: not expected to reach its limit within {horizon_text(p)} at this rate.{early}"
                + change_text(p))
    if not q or q.get("median") is None:
        early = ""
        if q and q.get("p05") is not None:  # the median lies beyond the horizon, the 5 % quantile within
            when = f", {date(d['p05'])}" if d and d.get("p05") else ""
            early = f" At the earliest (5 %): in {operations(q['p05'], par)}{when}."
        return (f"{who_cap}: not expected to reach its limit within {horizon_text(p)} at this rate. "
                f"{_lead(now, lim)}.{early}" + change_text(p))
    hi = operations(q["p95"], par) if q.get("p95") is not None else f"beyond {horizon_text(p)}"
    span = f"{int(round(q['p05'])):,}–{hi}" if q.get("p95") is not None else f"{operations(q['p05'], par)} to {hi}"
    when = ""
    if d and d.get("median"):
        dhi = date(d["p95"]) if d.get("p95") else "later"
        when = f", around {date(d['median'])} (90 %: {date(d['p05'])} – {dhi})"
    if q["median"] < 0.5:  # the median crossing is the next opening: it is at its limit now
        return (f"{who_cap} is at its limit: service is due (90 % interval {span}). "
                f"{_lead(now, lim)}. {action(par)}")
    return (f"{who_cap} reaches its limit in about {operations(q['median'], par)}{when}; 90 % interval "
            f"{span}. {_lead(now, lim)}. Trend since the {p['basis']}, "
            f"{p['basis_operations']} fits." + change_text(p))


def change_text(p: dict) -> str:
    """The change points' part in words: the chance of a change of pace before the crossing, and
    a level step with no maintenance logged."""
    out = ""
    c = p.get("change_before_crossing")
    q = p.get("operations_to_limit")
    if c is not None and q and q.get("median") is not None and c >= 0.005:
        out += f" Chance of a change of pace before the crossing: {c * 100:.0f} %."
    for note in p.get("notes") or []:
        out += f" Note: {note}."
    return out


def fleet_text(p: dict) -> str:
    """The fleet column's short form of the soonest prognosis."""
    par = p["parameter"]
    q, d = p.get("operations_to_limit"), p.get("date_to_limit")
    if p["status"] == "crossed":
        return f"{name(par)}: limit crossed, service due"
    if p.get("limit") is None:
        return f"{name(par)}: no prognosis yet"
    if p["status"] == "no trend":
        return f"{name(par)}: no trend, not within {horizon_text(p)}"
    if not q or q.get("median") is None:
        return f"{name(par)}: not within {horizon_text(p)}"
    if q["median"] < 0.5:
        return f"{name(par)}: at its limit, service due"
    when = f" (around {date(d['median'])})" if d and d.get("median") else ""
    return f"{name(par)}: limit in about {operations(q['median'], par)}{when}"
