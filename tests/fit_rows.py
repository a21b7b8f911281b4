"""Fits written straight into the fit table and fed to the worker's drift update (and so its
prognosis hook), for tests that need a history faster than real fits give it."""

from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np


def store_fit(s, *, key: str, breaker_id: int, occurred_at: datetime, result: dict, kind: str = "open"):
    """One operation and its done fit, written straight into the tables (no capture file)."""
    from service.storage import crud

    op, _ = crud.create_operation(s, capture_key=key, breaker_id=breaker_id, kind=kind, occurred_at=occurred_at,
                                  source="replay", capture_path="/nonexistent.csv", capture_sha256="0" * 64,
                                  flags=[], sample_rate=1.0, n_samples=1)
    crud.claim_fit(s, operation_id=op.id, worker="test")
    crud.store_fit_result(s, operation_id=op.id, curve=None, result=result)
    return op


def store_leak(Session, settings, *, t0: datetime, step: timedelta, n: int = 32, start: int = 25,
               breaker_id: int = 1, key: str = "leak") -> list:
    """Openings 0..n-1 of breaker ``breaker_id`` every ``step`` from ``t0``: DO 39.5 s^-1 with a
    0.3 % spread that falls 2 %/opening from ``start``; BO flat (0.2 % spread). Returns the drift
    update's events of each opening."""
    from service.jobs.fit import update_drift
    from service.storage import crud

    rng = np.random.default_rng(3)
    events = []
    for i in range(n):
        do = 39.5 * (1 + rng.normal(0, 0.003)) * (0.98 ** max(0, i - start))
        with Session() as s, s.begin():
            op, _ = crud.create_operation(s, capture_key=f"{key}{i}-{breaker_id}", breaker_id=breaker_id,
                                          kind="open", occurred_at=t0 + i * step, source="replay",
                                          capture_path="/nonexistent.csv", capture_sha256="0" * 64, flags=[],
                                          sample_rate=1.0, n_samples=1)
            crud.claim_fit(s, operation_id=op.id, worker="test")
            crud.store_fit_result(s, operation_id=op.id, curve=None, result={
                "parameters": {"AO": 3424.0, "BO": 4806.0 * (1 + rng.normal(0, 0.002)), "DO": do, "EO": 3950.0},
                "ci95": {"DO": [do - 0.3, do + 0.3], "BO": [4790.0, 4822.0]}, "identifiable": True})
            events.append(update_drift(s, breaker_id=breaker_id, settings=settings))
    return events
