"""The worker side of a refit: one task re-fits a batch of one breaker's operations.

A batch costs three database visits whatever its size: one read, the fits (no database), one
write transaction. Operations are in time order within the batch, so each fit warm-starts from
the one before it. The write is all-or-nothing and skips operations this run already refitted,
so a batch run twice (a redelivered Celery task, a resumed run) lands each result once.
"""

from __future__ import annotations

import bisect
import time

from sqlalchemy import delete, insert, select, update

from service.jobs.fit import JobOptions, _fit, failure_reason, warm_prior
from service.storage import crud
from service.storage.db import cached_engine, session_factory
from service.storage.models import (BreakerRow, FitRow, FitVersionRow, OperationRow, ParameterValueRow,
                                    RefitRunRow, utcnow)

_REASONS_KEPT = 20  # failure reasons kept on the run row


def refit_batch(run_id: int, operation_ids: list[int], options: JobOptions | dict) -> dict:
    """Re-fit ``operation_ids`` (one breaker) for refit run ``run_id``.

    Returns ``{"done", "failed", "skipped", "fit_s", "cpu_s"}``: ``skipped`` counts operations
    this run had already refitted; ``cpu_s`` is this process's CPU time for the whole batch. A
    failed re-fit keeps the current result (and says why on the run).
    """
    cpu0 = time.process_time()
    if isinstance(options, dict):
        options = JobOptions(**options)
    Session = session_factory(cached_engine(options.database_url))
    with Session() as session:
        ops = list(session.scalars(select(OperationRow).where(OperationRow.id.in_(operation_ids))
                                   .order_by(OperationRow.occurred_at, OperationRow.id)))
        fits = {f.operation_id: f for f in session.scalars(
            select(FitRow).where(FitRow.operation_id.in_(operation_ids)))}
        todo = [op for op in ops if op.id in fits and fits[op.id].refit_run_id != run_id]
        if not todo:
            return {"done": 0, "failed": 0, "skipped": len(operation_ids), "fit_s": 0.0,
                    "cpu_s": time.process_time() - cpu0}
        breaker_id = todo[0].breaker_id
        breaker = crud.breaker_model(session.get(BreakerRow, breaker_id))
        first = todo[0].occurred_at
        previous = {}
        for kind in ("open", "close"):
            row = crud.latest_good_fit(session, breaker_id=breaker_id, kind=kind, before=first,
                                       exclude_operation=todo[0].id)
            if row is not None and row.operation_id not in operation_ids:
                previous[kind] = (row.operation_id, row.result)
        openings = _opening_factors(session, breaker_id, todo[-1].occurred_at)
        jobs = [(op.id, op.kind, op.occurred_at, op.capture_path, op.capture_sha256) for op in todo]

    results, t0 = {}, time.perf_counter()
    for op_id, kind, occurred_at, path, sha in jobs:
        dc = dc_source = None
        if kind == "close":
            dc, dc_source = _dc_before(openings, occurred_at, breaker)
        try:
            result, curve = _fit(path, sha, breaker, kind, dc, options,
                                 warm_prior(breaker, kind, previous.get(kind)))
            if dc is not None:
                result["dc_used"], result["dc_source"] = dc, dc_source
            results[op_id] = (result, curve, None)
            previous[kind] = (op_id, result)
            if kind == "open" and result.get("identifiable", True):
                _insert_opening(openings, occurred_at, result["parameters"]["AO"])
        except Exception as exc:  # stored as the reason; the current result stays
            results[op_id] = (None, None, failure_reason(exc))
    fit_s = time.perf_counter() - t0
    done, failed, skipped = _store(Session, run_id, ops_by_id={op.id: op for op in todo},
                                   results=results)
    return {"done": done, "failed": failed, "skipped": skipped + len(operation_ids) - len(todo),
            "fit_s": fit_s, "cpu_s": time.process_time() - cpu0}


def _opening_factors(session, breaker_id: int, until) -> tuple[list, list]:
    """(times, AO values) of the breaker's good opening fits up to ``until``, in time order."""
    rows = session.execute(
        select(OperationRow.occurred_at, FitRow.parameters)
        .join(FitRow, FitRow.operation_id == OperationRow.id)
        .where(FitRow.breaker_id == breaker_id, FitRow.kind == "open", FitRow.status == "done",
               FitRow.identifiable.is_not(False), OperationRow.occurred_at <= until)
        .order_by(OperationRow.occurred_at)).all()
    pairs = [(t, float(p["AO"])) for t, p in rows if p and "AO" in p]
    return [t for t, _ in pairs], [v for _, v in pairs]


def _insert_opening(openings, t, ao) -> None:
    i = bisect.bisect_right(openings[0], t)
    openings[0].insert(i, t)
    openings[1].insert(i, float(ao))


def _dc_before(openings, t, breaker) -> tuple[float, str]:
    """DC = AO of the latest opening at or before ``t`` [s^-2]; the design value without one."""
    i = bisect.bisect_right(openings[0], t)
    if i:
        return openings[1][i - 1], "latest opening fit"
    return float(breaker.design_parameters()["DC"]), "breaker file design value"


def _store(Session, run_id: int, *, ops_by_id: dict, results: dict) -> tuple[int, int, int]:
    """One transaction: archive the current results, write the new ones, count them on the run.

    Bulk statements (one INSERT of the archived versions, one executemany UPDATE of the fits,
    one DELETE and one INSERT of the parameter values), not a round trip per fit.
    """
    now = utcnow()
    with Session() as session, session.begin():
        # Take the write lock first (SQLite), so no other writer slips in between read and write.
        session.execute(update(RefitRunRow).where(RefitRunRow.id == run_id)
                        .values(status=RefitRunRow.status))
        current = session.execute(
            select(FitRow.id, FitRow.operation_id, FitRow.refit_run_id, FitRow.version, FitRow.status,
                   FitRow.failure_reason, FitRow.parameters, FitRow.ci95, FitRow.rmse_rad, FitRow.result,
                   FitRow.finished_at)
            .where(FitRow.operation_id.in_(list(results))).with_for_update()).all()
        done = failed = skipped = 0
        archived, updates, values, reasons, refitted_ids = [], [], [], [], []
        for fit in current:
            if fit.refit_run_id == run_id:  # another attempt of this batch landed it
                skipped += 1
                continue
            result, curve, reason = results[fit.operation_id]
            if reason is not None:
                failed += 1
                reasons.append(f"operation {fit.operation_id}: {reason}")
                updates.append({"id": fit.id, "refit_run_id": run_id})
                continue
            archived.append(dict(fit_id=fit.id, operation_id=fit.operation_id, version=fit.version,
                                 status=fit.status, failure_reason=fit.failure_reason,
                                 parameters=fit.parameters, ci95=fit.ci95, rmse_rad=fit.rmse_rad,
                                 result=fit.result, finished_at=fit.finished_at, superseded_at=now,
                                 superseded_by_run=run_id))
            updates.append({"id": fit.id, "refit_run_id": run_id, "version": fit.version + 1,
                            **_new_values(result, curve, now)})
            refitted_ids.append(fit.id)
            op = ops_by_id[fit.operation_id]
            ci = result.get("ci95") or {}
            for name, value in (result.get("parameters") or {}).items():
                lo, hi = (ci.get(name) or (None, None))[:2]
                values.append(dict(fit_id=fit.id, operation_id=fit.operation_id, breaker_id=op.breaker_id,
                                   kind=op.kind, name=name, value=float(value),
                                   ci_low=None if lo is None else float(lo),
                                   ci_high=None if hi is None else float(hi),
                                   identifiable=bool(result.get("identifiable", True)),
                                   occurred_at=op.occurred_at))
            done += 1
        if archived:
            session.execute(insert(FitVersionRow), archived)
        # Failures only mark the row; successes replace every result field.
        for group in ([u for u in updates if "version" in u], [u for u in updates if "version" not in u]):
            if group:
                session.execute(update(FitRow), group)
        if refitted_ids:
            session.execute(delete(ParameterValueRow).where(ParameterValueRow.fit_id.in_(refitted_ids)))
        if values:
            session.execute(insert(ParameterValueRow), values)
        run = session.get(RefitRunRow, run_id)
        run.done += done
        run.failed += failed
        if reasons:
            kept = (run.reason or "").splitlines()
            run.reason = "\n".join((kept + reasons)[:_REASONS_KEPT])
    return done, failed, skipped


def _new_values(result: dict, curve, now) -> dict:
    """The fits row's result columns (the same fields ``crud.store_fit_result`` writes)."""
    from service.storage.crud import fit_result_values

    return fit_result_values(result, curve, now)
