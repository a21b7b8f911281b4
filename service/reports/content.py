"""What a condition report says, read from the database: the I/O side of the report.

Everything the PDF shows is gathered here into plain data (``ReportContent``), so the layout
(``pdf``) and the figures (``figures``) never touch the database. Long series are decimated
(min/max per bucket, service.decimation) while they are read: a breaker with 10,000 operations
gives a few hundred points per trend, and no excursion is lost.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime

import numpy as np
from sqlalchemy import func, select

from service import __version__
from service.breaker_file import BreakerFileError, parse_breaker_text
from service.decimation import minmax_indices
from service.display import parameter_label, quantity, watched_words
from service.mechanics.nomenclature import CLOSING, OPENING, UNITS
from service.storage import crud_alarms, crud_diagnoses
from service.storage.models import (AlarmRow, BreakerRow, DriftStateRow, FitRow, OperationRow,
                                    ParameterValueRow, utcnow)

from .verdicts import Verdict, characteristic_verdicts, parameter_verdicts
from .window import Window

# Buckets per trend: each keeps its minimum and maximum, so at most 2·TREND_BUCKETS + 2 points,
# about one per 0.3 mm of a 160 mm wide plot at 300 buckets: finer than the printed line.
TREND_BUCKETS = 300
ALARM_ROWS = 200  # alarms listed in the report (the CSV export holds them all)

FIT_METHOD = ("Each operation's travel is fitted with the reduced dynamic model of the mechanism "
              "(Yan et al. 2026) by CMA-ES; the 95 % intervals come from the fit's curvature. Drift "
              "alarms: a two-sided CUSUM of each watched parameter against its own temperature-"
              "compensated baseline (docs/alarms.md). Prognosis: the compensated trend since the "
              "change point projected to the breaker file's limits (docs/prognosis.md).")


@dataclass
class LatestOperation:
    """The latest fitted opening or closing in the window."""

    operation_id: int
    kind: str
    occurred_at: datetime
    parameters: dict
    ci95: dict
    characteristics: dict
    rmse_rad: float | None
    identifiable: bool | None
    fit_version: int
    characteristic_verdicts: list[Verdict]
    parameter_verdicts: list[Verdict]
    curve: dict | None = None  # {"t_s", "measured_rad", "fitted_rad"} or None
    curve_note: str = ""


@dataclass
class Trend:
    """One parameter's decimated history: times, values and their 95 % band."""

    name: str
    unit: str
    t: list[datetime]
    value: np.ndarray
    low: np.ndarray
    high: np.ndarray
    count: int  # values in the window before decimation
    baseline: float | None = None
    limits: list[tuple[str, float]] = field(default_factory=list)  # ("falling"|"rising", value)
    alarms: list[tuple[datetime, str]] = field(default_factory=list)  # (raised at, level)


@dataclass
class ReportContent:
    breaker: BreakerRow
    identity: list[tuple[str, str]]
    window: Window
    generated_at: datetime
    counts: dict
    latest: dict[str, LatestOperation | None]
    trends: list[Trend]
    alarms: list[AlarmRow]
    alarm_actions: dict[int, list]
    active_alarms: list[AlarmRow]
    prognoses: list
    diagnosis: dict | None
    method: list[tuple[str, str]]
    file_problem: str = ""
    limit_words: dict[str, str] = field(default_factory=dict)  # parameter -> its maintenance limit in words
    maintenance: list = field(default_factory=list)  # the maintenance log, newest first (issue 50)


def _baselines(session, breaker_id: int) -> dict[str, float | None]:
    out = {}
    for row in session.scalars(select(DriftStateRow).where(DriftStateRow.breaker_id == breaker_id)):
        b = (row.state or {}).get("baseline") or {}
        out[row.parameter] = b.get("mean") if isinstance(b, dict) else None
    return out


def _latest(session, breaker: BreakerRow, kind: str, window: Window, file_model, baselines,
            breaker_model) -> LatestOperation | None:
    q = (select(FitRow, OperationRow).join(OperationRow, OperationRow.id == FitRow.operation_id)
         .where(FitRow.breaker_id == breaker.id, FitRow.kind == kind, FitRow.status == "done",
                OperationRow.clock_suspect.is_(False), *window.where(OperationRow.occurred_at))
         .order_by(OperationRow.occurred_at.desc(), FitRow.id.desc()).limit(1))
    row = session.execute(q).first()
    if row is None:
        return None
    fit, op = row
    names = OPENING if kind == "open" else CLOSING
    char_limits = getattr(file_model.characteristic_limits, kind) if file_model is not None else {}
    limits = dict(file_model.limits.items()) if file_model is not None else {}
    latest = LatestOperation(
        operation_id=op.id, kind=kind, occurred_at=op.occurred_at, parameters=dict(fit.parameters or {}),
        ci95=dict(fit.ci95 or {}), characteristics=dict(fit.characteristics or {}), rmse_rad=fit.rmse_rad,
        identifiable=fit.identifiable, fit_version=fit.version,
        characteristic_verdicts=characteristic_verdicts(fit.characteristics, char_limits),
        parameter_verdicts=parameter_verdicts(fit.parameters, names, limits, baselines, UNITS))
    latest.curve, latest.curve_note = _curve(op, fit, breaker_model)
    return latest


def _curve(op: OperationRow, fit: FitRow, breaker_model) -> tuple[dict | None, str]:
    """The measured travel and the fitted model of an operation, decimated, or a note why not."""
    from drivers.capture import CaptureError
    from service.acquisition.capture_file import read_stored_capture
    from service.storage.fit_curve import fit_curve

    if breaker_model is None:
        return None, "the stored breaker file does not load"
    try:
        cap = read_stored_capture(op.capture_path, breaker_model)
    except (CaptureError, OSError, ValueError):
        return None, "the raw capture is no longer stored (retention) or unreadable"
    idx = minmax_indices(cap.travel, 1000)
    t = np.asarray(cap.t)[idx]
    measured = np.asarray(cap.travel)[idx]
    fitted = None
    curve = fit_curve(fit, cap.t, breaker_model)
    if curve is not None:
        ft, fv = curve
        fitted = np.where((t >= ft[0]) & (t <= ft[-1]), np.interp(t, ft, fv), np.nan)
    return {"t_s": t, "measured_rad": measured, "fitted_rad": fitted}, ""


def _trends(session, breaker: BreakerRow, window: Window, baselines, file_model, alarms) -> list[Trend]:
    suspect = select(OperationRow.id).where(OperationRow.breaker_id == breaker.id,
                                            OperationRow.clock_suspect.is_(True))
    q = (select(ParameterValueRow.name, ParameterValueRow.occurred_at, ParameterValueRow.value,
                ParameterValueRow.ci_low, ParameterValueRow.ci_high)
         .where(ParameterValueRow.breaker_id == breaker.id, ParameterValueRow.operation_id.not_in(suspect),
                *window.where(ParameterValueRow.occurred_at))
         .order_by(ParameterValueRow.name, ParameterValueRow.occurred_at, ParameterValueRow.id))
    by_name: dict[str, list] = {}
    for name, t, v, lo, hi in session.execute(q):
        by_name.setdefault(name, []).append((t, v, lo, hi))
    limits = dict(file_model.limits.items()) if file_model is not None else {}
    alarm_times = _alarm_times(session, alarms)
    out = []
    for name in (*OPENING, "CO", *CLOSING):
        rows = by_name.get(name)
        if not rows:
            continue
        value = np.array([r[1] for r in rows], float)
        keep = minmax_indices(value, TREND_BUCKETS)
        low = np.array([np.nan if rows[i][2] is None else rows[i][2] for i in keep], float)
        high = np.array([np.nan if rows[i][3] is None else rows[i][3] for i in keep], float)
        base = baselines.get(name)
        bounds = []
        if name in limits:
            lim = limits[name]
            relative = lim.min_change is not None or lim.max_change is not None
            if base or not relative:
                bounds = lim.bounds(base if base else 1.0)
        out.append(Trend(name=name, unit=UNITS.get(name, ""), t=[rows[i][0] for i in keep], value=value[keep],
                         low=low, high=high, count=len(rows), baseline=base, limits=bounds,
                         alarms=[(alarm_times.get(a.id, a.raised_at), a.level) for a in alarms if a.parameter == name]))
    return out


def _alarm_times(session, alarms) -> dict[int, datetime]:
    """Alarm id -> the time of the operation that raised it (where the trend shows it)."""
    ids = {a.operation_id for a in alarms if a.operation_id is not None}
    if not ids:
        return {}
    times = {i: t for i, t in session.execute(select(OperationRow.id, OperationRow.occurred_at)
                                              .where(OperationRow.id.in_(ids)))}
    return {a.id: times[a.operation_id] for a in alarms if a.operation_id in times}


def _counts(session, breaker_id: int, window: Window) -> dict:
    q = (select(OperationRow.kind, FitRow.status, func.count(), func.min(OperationRow.occurred_at),
                func.max(OperationRow.occurred_at))
         .outerjoin(FitRow, FitRow.operation_id == OperationRow.id)
         .where(OperationRow.breaker_id == breaker_id, *window.where(OperationRow.occurred_at))
         .group_by(OperationRow.kind, FitRow.status))
    out = {"open": 0, "close": 0, "done": 0, "failed": 0, "pending": 0, "first": None, "last": None}
    for kind, status, n, first, last in session.execute(q):
        out[kind] = out.get(kind, 0) + n
        out["done" if status == "done" else "failed" if status == "failed" else "pending"] += n
        for key, t, pick in (("first", first, min), ("last", last, max)):
            if isinstance(t, str):  # SQLite answers an aggregate of a DateTime as text
                t = datetime.fromisoformat(t)
            if t is not None:
                from .window import utc

                t = utc(t)
                out[key] = t if out[key] is None else pick(out[key], t)
    return out


def _diagnosis(session, breaker_id: int) -> dict | None:
    row = crud_diagnoses.latest(session, breaker_id=breaker_id)
    if row is None:
        return None
    r = row.result or {}
    return {"id": row.id, "status": row.status, "operation": row.operation, "captures": len(row.operation_ids or []),
            "requested_at": row.requested_at, "finished_at": row.finished_at,
            "message": r.get("message") or row.failure_reason or "",
            "answer": r.get("answer_in_words") or r.get("answer") or "",
            "probability": r.get("answer_probability")}


def gather(session, *, breaker: BreakerRow, settings, window: Window = Window()) -> ReportContent:
    """Everything the condition report of ``breaker`` shows, over ``window``. ``settings`` are the
    drift detector's (``Settings.drift_settings``)."""
    from service.jobs.prognosis import breaker_prognoses
    from service.storage import crud

    settings = settings.for_breaker(breaker.name)  # its [alarms.breakers.NAME] overrides
    file_problem = ""
    try:
        file_model = parse_breaker_text(breaker.breaker_file, source=f"of breaker {breaker.name!r}")
    except BreakerFileError as exc:
        file_model, file_problem = None, str(exc)
    try:
        model = crud.breaker_model(breaker)
    except (BreakerFileError, ValueError):
        model = None
    baselines = _baselines(session, breaker.id)
    alarms = list(session.scalars(select(AlarmRow).where(AlarmRow.breaker_id == breaker.id,
                                                         *window.where(AlarmRow.raised_at))
                                  .order_by(AlarmRow.raised_at.desc(), AlarmRow.id.desc()).limit(ALARM_ROWS)))
    active = [a for a in crud.list_alarms(session, state="active", breaker_id=breaker.id)]
    actions: dict[int, list] = {}
    for act in crud_alarms.list_actions(session, breaker_id=breaker.id, limit=10 * ALARM_ROWS):
        if act.alarm_id is not None:
            actions.setdefault(act.alarm_id, []).append(act)
    for acts in actions.values():
        acts.sort(key=lambda a: (a.at, a.id))
    identity = [("Name", breaker.name), ("Tag", breaker.tag), ("Breaker id", str(breaker.id)),
                ("Breaker file", f"SHA-256 {breaker.content_sha256[:16]}…, cam table {breaker.cam_file_name or '—'}"),
                ("Registered in hvcb", breaker.created_at.strftime("%Y-%m-%d %H:%M UTC")),
                ("Baseline since", breaker.baseline_reset_at.strftime("%Y-%m-%d %H:%M UTC")
                 if breaker.baseline_reset_at else "its first operations")]
    if model is not None:
        design = model.design_parameters()
        identity.append(("Design parameters", ", ".join(f"{parameter_label(k)} {quantity(design[k], k, 4)}"
                                                         for k in (*OPENING, *CLOSING) if k in design)))
    if breaker.out_of_service_since:
        identity.append(("Out of service", f"since {breaker.out_of_service_since:%Y-%m-%d %H:%M} UTC: "
                                            f"{breaker.out_of_service_reason or ''}"))
    versions = session.execute(select(func.min(FitRow.version), func.max(FitRow.version))
                               .where(FitRow.breaker_id == breaker.id, FitRow.status == "done")).one()
    method = [("hvcb", __version__), ("Method", FIT_METHOD),
              ("Fit versions", "—" if versions[0] is None else
               (f"{versions[0]}" if versions[0] == versions[1] else f"{versions[0]} to {versions[1]}")
               + " (hvcb refit raises an operation's version)"),
              ("Drift detector", f"baseline of {settings.baseline_n} fits; allowance {settings.k:g} σ, warning at "
                                 f"{settings.h_warning:.3g} σ, alarm at {settings.h_alarm:.3g} σ (σ: the breaker's own "
                                 "run-to-run spread); watched: "
                                 + ", ".join(f"{parameter_label(k)} {watched_words(v)}" for k, v in settings.watched.items()))]
    progs = breaker_prognoses(session, breaker=breaker, settings=settings)
    if progs:
        method.append(("Prognosis model", progs[0].model))
    return ReportContent(
        breaker=breaker, identity=identity, window=window, generated_at=utcnow(),
        counts=_counts(session, breaker.id, window),
        latest={k: _latest(session, breaker, k, window, file_model, baselines, model) for k in ("open", "close")},
        trends=_trends(session, breaker, window, baselines, file_model, alarms),
        alarms=alarms, alarm_actions=actions, active_alarms=active, prognoses=progs,
        diagnosis=_diagnosis(session, breaker.id), method=method, file_problem=file_problem,
        limit_words={k: lim.words(UNITS.get(k, "")) for k, lim in (file_model.limits.items() if file_model else [])},
        maintenance=_maintenance(session, breaker.id))


def _maintenance(session, breaker_id: int) -> list:
    """The breaker's maintenance log (service/storage/maintenance.py), newest first."""
    from service.storage.maintenance import list_events

    return list_events(session, breaker_id)
