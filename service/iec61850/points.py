"""The IEC 61850 point map: which logical devices, nodes and data objects hvcb serves, and their
values. Pure: no I/O, no clock, no libiec61850 (``server.py`` is the transport).

IED ``hvcb``; one logical device per breaker whose instance is the breaker's SCADA tag, so the
reference breaker (tag ``Q1``) is ``hvcbQ1``. Logical nodes and data-object names follow
IEC 61850-7-4 (XCBR, SCBR, SOPM, LLN0, LPHD). hvcb's own quantities (the fitted parameters and
their drift alarms) are extension data objects in SOPM: each carries ``dataNs`` = ``hvcb:2026A``
(IEC 61850-7-1 rule for a data object that is not in its logical node's namespace).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Iterable, Mapping

from service.mechanics.nomenclature import CLOSING, OPENING, machine_unit

IED_NAME = "hvcb"
STANDARD_NS = "IEC 61850-7-4:2007B"  # ldNs of every logical device (7-4 Edition 2)
HVCB_NS = "hvcb:2026A"               # dataNs of hvcb's extension data objects

PARAMETER_MEANING = {  # (meaning, unit): the units from the nomenclature, in ASCII
    name: (meaning, machine_unit(name)) for name, meaning in (
        ("AO", "opening spring stiffness factor kO rO^2/J2"),
        ("BO", "opening spring force factor (kO xO1 rO - TOf)/J2"),
        ("DO", "buffer damping factor cb rb^2/J2"),
        ("EO", "buffer stiffness factor kb rb^2/J2"),
        ("AC", "closing spring factor kC rC d/J1"),
        ("BC", "inertia ratio J2/J1"),
        ("CC", "closing resistance factor (TCf + kO xO0 rO)/J2"))}

# Watched names that are not fitted parameters, as data-object names (IEC 61850-7-1: letters and
# digits, short): the vibration's trip-latch time (service.vibration).
DO_NAMES = {"latch_time_s": "LatTm", "buffer_ratio": "BufRt"}
PARAMETER_OF = {v: k for k, v in DO_NAMES.items()}

# Data attributes of each common data class as hvcb serves them: (name, FC, type).
CDC_ATTRIBUTES = {
    "SPS": (("stVal", "ST", "BOOLEAN"), ("q", "ST", "Quality"), ("t", "ST", "Timestamp")),
    "INS": (("stVal", "ST", "INT32"), ("q", "ST", "Quality"), ("t", "ST", "Timestamp")),
    "ENS": (("stVal", "ST", "Enum"), ("q", "ST", "Quality"), ("t", "ST", "Timestamp")),
    "MV": (("mag.f", "MX", "FLOAT32"), ("q", "MX", "Quality"), ("t", "MX", "Timestamp")),
    "DPC": (("stVal", "ST", "Dbpos"), ("q", "ST", "Quality"), ("t", "ST", "Timestamp"),
            ("ctlModel", "CF", "Enum")),
    "LPL": (("vendor", "DC", "VisString255"), ("swRev", "DC", "VisString255"),
            ("d", "DC", "VisString255"), ("configRev", "DC", "VisString255"),
            ("ldNs", "EX", "VisString255")),
    "DPL": (("vendor", "DC", "VisString255"),),
}
EXTENSION_ATTRIBUTES = (("dataNs", "EX", "VisString255"), ("d", "DC", "VisString255"))

# Qualities the transport maps to IEC 61850-7-3 quality bits.
GOOD, INVALID, OLD, INACCURATE = "good", "invalid", "questionable-old", "questionable-inaccurate"
HEALTH = {"none": 1, "warning": 2, "alarm": 3}  # ENS Health: Ok, Warning, Alarm
POS_OFF, POS_ON, POS_INTERMEDIATE = "off", "on", "intermediate"

_LD_INST = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


@dataclass(frozen=True)
class DataObject:
    """One data object of a logical node. ``namespace`` None = the standard (7-4) one."""

    ln: str
    name: str
    cdc: str
    meaning: str
    namespace: str | None = None
    unit: str = ""

    @property
    def attributes(self) -> tuple:
        extra = EXTENSION_ATTRIBUTES if self.namespace else ()
        return CDC_ATTRIBUTES[self.cdc] + extra


@dataclass(frozen=True)
class LogicalDevice:
    inst: str                # the breaker's SCADA tag
    breaker: str             # the breaker's name
    objects: tuple[DataObject, ...]
    dataset: tuple[str, ...]  # "LN.DO" members of the alarm dataset (FC ST)

    @property
    def name(self) -> str:
        return IED_NAME + self.inst

    @property
    def logical_nodes(self) -> list[str]:
        return list(dict.fromkeys(o.ln for o in self.objects))


@dataclass(frozen=True)
class Point:
    """One data attribute: a row of the point map."""

    reference: str   # LD/LN.DO.DA
    fc: str
    type: str
    meaning: str
    namespace: str


DATASET = "Alarms"     # per logical device, in LLN0
RCB = "urcbAlarms"     # unbuffered report control block on that dataset, in LLN0


def ld_inst_problem(tag: str) -> str | None:
    """Why ``tag`` cannot be a logical-device instance, or None."""
    if not _LD_INST.match(tag or ""):
        return (f"SCADA tag {tag!r} cannot be an IEC 61850 logical-device instance "
                f"(letters, digits and _ only, starting with a letter)")
    if len(IED_NAME + tag) > 64:
        return f"SCADA tag {tag!r} is too long for an IEC 61850 logical-device name (64 characters)"
    return None


def logical_device(tag: str, breaker: str, watched: Iterable[str]) -> LogicalDevice:
    """The logical device of one breaker. ``watched``: the drift-watched parameters (DO, BO)."""
    problem = ld_inst_problem(tag)
    if problem:
        raise ValueError(f"breaker {breaker!r}: {problem}")
    objs = [
        DataObject("LLN0", "Mod", "ENS", "mode: 1 = on"),
        DataObject("LLN0", "Beh", "ENS", "behaviour: 1 = on"),
        DataObject("LLN0", "Health", "ENS", "worst of SCBR1 and SOPM1 Health: 1 ok, 2 warning, 3 alarm"),
        DataObject("LLN0", "NamPlt", "LPL", "name plate; ldNs = " + STANDARD_NS),
        DataObject("LPHD1", "PhyNam", "DPL", "physical device name plate (vendor hvcb)"),
        DataObject("LPHD1", "PhyHealth", "ENS", "1 ok, 2 warning = this breaker's DAQ is down"),
        DataObject("LPHD1", "Proxy", "SPS", "true: hvcb is a proxy for the breaker's mechanism"),
        DataObject("XCBR1", "Beh", "ENS", "behaviour: 1 = on"),
        DataObject("XCBR1", "OpCnt", "INS", "operation counter: operations recorded (open + close)"),
        DataObject("XCBR1", "Pos", "DPC", "position after the last recorded operation "
                                          "(status only, ctlModel 0)"),
        DataObject("SCBR1", "Beh", "ENS", "behaviour: 1 = on"),
        DataObject("SCBR1", "Health", "ENS", "operating-time drift: 1 ok, 2 warning, 3 alarm"),
        DataObject("SCBR1", "OpTmOpn", "MV", "opening time of the last opening (travel to contact "
                                             "separation)", unit="s"),
        DataObject("SCBR1", "OpTmCls", "MV", "closing time of the last closing (travel to contact "
                                             "touch)", unit="s"),
        DataObject("SCBR1", "OpTmWrn", "SPS", "operating time drifted from its baseline: warning level"),
        DataObject("SCBR1", "OpTmAlm", "SPS", "operating time drifted from its baseline: alarm level"),
        DataObject("SOPM1", "Beh", "ENS", "behaviour: 1 = on"),
        DataObject("SOPM1", "Health", "ENS", "mechanism-parameter drift: 1 ok, 2 warning, 3 alarm"),
    ]
    for name in OPENING + CLOSING:
        meaning, unit = PARAMETER_MEANING[name]
        kind = "opening" if name in OPENING else "closing"
        objs.append(DataObject("SOPM1", name, "MV", f"{meaning}, last {kind} fit", HVCB_NS, unit))
    objs.append(DataObject("SOPM1", "LatTm", "MV", "trip latch time of the last opening: the vibration's "
                                                   "first shock to the start of motion", HVCB_NS, "s"))
    members = ["SCBR1.OpTmWrn", "SCBR1.OpTmAlm"]
    for name in watched:
        do = DO_NAMES.get(name, name)
        objs.append(DataObject("SOPM1", f"{do}Wrn", "SPS", f"{name} drift alarm raised (warning "
                                                             f"or alarm level)", HVCB_NS))
        objs.append(DataObject("SOPM1", f"{do}Alm", "SPS", f"{name} drift alarm at alarm level", HVCB_NS))
        members += [f"SOPM1.{do}Wrn", f"SOPM1.{do}Alm"]
    objs.append(DataObject("SOPM1", "OpsToLim", "MV", "median openings until the soonest maintenance "
                                                      "limit is crossed (prognosis); invalid: no limits, or "
                                                      "no crossing within the horizon", HVCB_NS, "1"))
    members += ["SOPM1.Health", "LLN0.Health"]
    return LogicalDevice(inst=tag, breaker=breaker, objects=tuple(objs), dataset=tuple(members))


def points(ld: LogicalDevice) -> list[Point]:
    """Every data attribute of ``ld``, in model order."""
    out = []
    for o in ld.objects:
        ns = "hvcb (dataNs " + o.namespace + ")" if o.namespace else "IEC 61850-7-4"
        unit = f" [{o.unit}]" if o.unit and o.unit != "1" else ""
        for da, fc, typ in o.attributes:
            out.append(Point(f"{ld.name}/{o.ln}.{o.name}.{da}", fc, typ, o.meaning + unit, ns))
    return out


def description(o: DataObject) -> str:
    """Text of the ``d`` attribute of an extension data object."""
    return o.meaning + (f" [{o.unit}]" if o.unit else "")


# -- values --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FitView:
    """The latest finished fit of one kind, as the point map needs it."""

    parameters: Mapping[str, float]
    identifiable: bool | None
    occurred_at: datetime
    operating_time_s: float | None = None
    latch_time_s: float | None = None


@dataclass(frozen=True)
class BreakerView:
    """What the database says about one breaker right now (read by ``snapshot.py``)."""

    name: str
    tag: str
    operations: int = 0
    last_kind: str | None = None
    last_operation_at: datetime | None = None
    fits: Mapping[str, FitView | None] = field(default_factory=dict)   # "open" / "close"
    alarms: Mapping[str, str] = field(default_factory=dict)            # parameter -> active level
    operating_time_levels: Mapping[str, str] = field(default_factory=dict)  # kind -> drift level
    daq_down: bool = False
    # (parameter, median openings to its limit or None: no crossing within the horizon, time);
    # None: no limits (service.jobs.prognosis.soonest_by_breaker)
    soonest: tuple | None = None


@dataclass(frozen=True)
class Value:
    """The value of one data object: ``value`` for stVal / mag.f, its quality and time stamp."""

    value: object
    quality: str
    t: datetime | None


def _worst(levels: Iterable[str]) -> str:
    best = "none"
    for lv in levels:
        if HEALTH.get(lv, 1) > HEALTH[best]:
            best = lv
    return best


def values(ld: LogicalDevice, view: BreakerView, *, now: datetime, stale_after_s: float) -> dict[str, Value]:
    """Value of every status/measured data object of ``ld`` ("LN.DO" -> Value)."""
    stale = timedelta(seconds=stale_after_s)
    out: dict[str, Value] = {}
    on = Value(1, GOOD, now)
    for ln in ("LLN0", "XCBR1", "SCBR1", "SOPM1"):
        out[f"{ln}.Beh"] = on
    out["LLN0.Mod"] = on
    out["LPHD1.PhyHealth"] = Value(2 if view.daq_down else 1, GOOD, now)
    out["LPHD1.Proxy"] = Value(True, GOOD, now)
    out["XCBR1.OpCnt"] = Value(int(view.operations), GOOD, view.last_operation_at or now)
    if view.last_kind is None:
        out["XCBR1.Pos"] = Value(POS_INTERMEDIATE, INVALID, now)
    else:
        out["XCBR1.Pos"] = Value(POS_OFF if view.last_kind == "open" else POS_ON, GOOD, view.last_operation_at)

    for kind, do in (("open", "OpTmOpn"), ("close", "OpTmCls")):
        fit = view.fits.get(kind)
        tm = fit.operating_time_s if fit is not None else None
        if tm is None:
            out[f"SCBR1.{do}"] = Value(None, INVALID, fit.occurred_at if fit else None)
        else:
            out[f"SCBR1.{do}"] = Value(float(tm), OLD if view.daq_down or now - fit.occurred_at > stale else GOOD,
                                       fit.occurred_at)
    tm_level = _worst(view.operating_time_levels.values())
    out["SCBR1.OpTmWrn"] = Value(tm_level in ("warning", "alarm"), GOOD, now)
    out["SCBR1.OpTmAlm"] = Value(tm_level == "alarm", GOOD, now)
    out["SCBR1.Health"] = Value(HEALTH[tm_level], GOOD, now)

    for name in OPENING + CLOSING:
        fit = view.fits.get("open" if name in OPENING else "close")
        if fit is None or name not in (fit.parameters or {}) or fit.parameters[name] is None:
            out[f"SOPM1.{name}"] = Value(None, INVALID, fit.occurred_at if fit else None)
            continue
        if view.daq_down or now - fit.occurred_at > stale:
            q = OLD
        elif fit.identifiable is False:
            q = INACCURATE
        else:
            q = GOOD
        out[f"SOPM1.{name}"] = Value(float(fit.parameters[name]), q, fit.occurred_at)
    opening = view.fits.get("open")
    latch = opening.latch_time_s if opening is not None else None
    out["SOPM1.LatTm"] = (Value(None, INVALID, opening.occurred_at if opening else None) if latch is None else
                          Value(float(latch), OLD if view.daq_down or now - opening.occurred_at > stale else GOOD,
                                opening.occurred_at))
    drift_levels = []
    for o in ld.objects:
        if o.ln == "SOPM1" and o.namespace and o.name.endswith(("Wrn", "Alm")):
            param, suffix = o.name[:-3], o.name[-3:]
            param = PARAMETER_OF.get(param, param)
            level = view.alarms.get(param, "none")
            drift_levels.append(level)
            active = level in ("warning", "alarm") if suffix == "Wrn" else level == "alarm"
            out[f"SOPM1.{o.name}"] = Value(active, GOOD, now)
    soon = view.soonest
    out["SOPM1.OpsToLim"] = (Value(float(soon[1]), GOOD, soon[2]) if soon is not None and soon[1] is not None
                             else Value(None, INVALID, soon[2] if soon is not None else now))
    mech = _worst(drift_levels)
    out["SOPM1.Health"] = Value(HEALTH[mech], GOOD, now)
    out["LLN0.Health"] = Value(HEALTH[_worst((mech, tm_level))], GOOD, now)
    return out


def operating_time_level(history: Iterable[tuple], settings) -> str:
    """Drift level ("none" | "warning" | "alarm") of one operating-time series.

    ``history``: (operation_id, time, operating_time_s) of identifiable fits in operation order.
    The project's own CUSUM detector (service.alarms.drift) watches it two-sided with the same
    settings as the mechanism parameters: a baseline of the first ``baseline_n`` fits, then
    warning/alarm when the time drifts either way.
    """
    from service.alarms import FitObservation, replay

    obs = [FitObservation(operation_id=i, time=t, value=v) for i, t, v in history]
    local = settings.__class__.from_mapping({**settings.to_dict(), "watched": {"OpTm": "both"}})
    state, _ = replay(obs, local, parameter="OpTm")
    return state.level


def markdown_table(ld: LogicalDevice) -> str:
    """The point map of ``ld`` as a Markdown table, one row per data object (docs/iec61850.md)."""
    rows = ["| LD/LN.DO | CDC | data attributes (FC, type) | meaning | namespace |",
            "|---|---|---|---|---|"]
    for o in ld.objects:
        das = ", ".join(f"`{da}` {fc} {typ}" for da, fc, typ in o.attributes)
        ns = f"hvcb (`dataNs` {o.namespace})" if o.namespace else "IEC 61850-7-4"
        unit = f" [{o.unit}]" if o.unit and o.unit != "1" else ""
        rows.append(f"| `{ld.name}/{o.ln}.{o.name}` | {o.cdc} | {das} | {o.meaning}{unit} | {ns} |")
    return "\n".join(rows)
