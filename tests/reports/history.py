"""A long stored history written in bulk (no fitting): operations, their finished fits and the
parameter rows, inserted a few thousand rows per statement, then one drift update so the alarms
and the prognosis are the detector's own. 10,000 operations take a few seconds."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np

T0 = datetime(2025, 1, 6, 6, 0, tzinfo=timezone.utc)
# The reference breaker's simulated characteristics (nominal fits, config/breakers/reference-252kV.toml)
CHARS = {"open": {"operating_time_s": 0.0112, "average_speed_rad_s": 32.63, "max_travel_rad": 1.057,
                  "overtravel_rad": 0.0251, "rebound_rad": 0.0015, "damping_time_s": 0.0390},
         "close": {"operating_time_s": 0.02868, "average_speed_rad_s": 57.63, "max_travel_rad": 1.0005,
                   "overtravel_rad": 0.0005, "rebound_rad": 0.0005, "damping_time_s": 0.0026}}


def fit_result(kind: str, design: dict, rng, leak: float) -> dict:
    names = ("AO", "BO", "DO", "EO") if kind == "open" else ("AC", "BC", "CC")
    params, ci = {}, {}
    for n in names:
        v = float(design[n] * (1 + rng.normal(0, 0.004)) * (leak if n == "DO" else 1.0))
        half = abs(v) * 0.006
        params[n], ci[n] = v, [v - half, v + half]
    ch = {k: float(v * (1 + rng.normal(0, 0.003))) for k, v in CHARS[kind].items()}
    if kind == "open":  # less buffer damping: more overtravel, a longer damping
        ch["overtravel_rad"] /= leak
    return {"parameters": params, "ci95": ci, "characteristics": ch, "rmse_rad": 0.0015}


def bulk_history(Session, settings, breaker, *, capture_path: str, n: int = 10_000, breaker_id: int = 1,
                 leak_from: float = 0.97, leak_per_op: float = 0.997, seed: int = 1,
                 step: timedelta = timedelta(hours=6)) -> dict:
    """``n`` operations of breaker ``breaker_id`` every ``step`` from T0 (every 4th a closing),
    each with a done fit; DO falls ``leak_per_op`` per opening after ``leak_from`` of the history.
    Every operation points at ``capture_path``. Returns {"fits": {operation id: result}, ...}."""
    from sqlalchemy import func, insert, select

    from service.jobs.fit import update_drift
    from service.storage.models import FitRow, OperationRow, ParameterValueRow

    rng = np.random.default_rng(seed)
    design = breaker.design_parameters()
    with Session() as s, s.begin():
        first = int(s.scalar(select(func.max(OperationRow.id))) or 0) + 1
        fit_first = int(s.scalar(select(func.max(FitRow.id))) or 0) + 1
        ops, fits, values, results = [], [], [], {}
        start = int(leak_from * n)
        for i in range(n):
            op_id, fit_id = first + i, fit_first + i
            kind = "close" if i % 4 == 3 else "open"
            leak = leak_per_op ** max(0, i - start) if kind == "open" else 1.0
            at = T0 + i * step
            r = fit_result(kind, design, rng, leak)
            results[op_id] = r
            ops.append(dict(id=op_id, breaker_id=breaker_id, kind=kind, capture_key=f"bulk-{breaker_id}-{op_id}",
                            occurred_at=at, received_at=at, source="daq", capture_path=capture_path,
                            capture_sha256="0" * 64, flags=[], sample_rate=128000.0, n_samples=20480,
                            clock_suspect=False, temperature_c=None, temperature_source=None))
            fits.append(dict(id=fit_id, operation_id=op_id, breaker_id=breaker_id, kind=kind, status="done",
                             attempts=1, results_stored=1, parameters=r["parameters"], ci95=r["ci95"],
                             rmse_rad=r["rmse_rad"], identifiable=True, characteristics=r["characteristics"],
                             window_start_s=None, onset_delay_s=None, warnings=[], version=1, queued_at=at,
                             finished_at=at))
            for name, v in r["parameters"].items():
                lo, hi = r["ci95"][name]
                values.append(dict(fit_id=fit_id, operation_id=op_id, breaker_id=breaker_id, kind=kind, name=name,
                                   value=v, ci_low=lo, ci_high=hi, identifiable=True, occurred_at=at))
        conn = s.connection()  # Core inserts: executemany without the ORM's per-row bookkeeping
        for table, rows in ((OperationRow, ops), (FitRow, fits), (ParameterValueRow, values)):
            for k in range(0, len(rows), 5000):
                conn.execute(insert(table.__table__), rows[k:k + 5000])
        events = update_drift(s, breaker_id=breaker_id, settings=settings)
    return {"results": results, "events": events, "first_id": first}
