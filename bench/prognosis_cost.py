"""The worker's prognosis cost per fit against the breaker's age, with and without the window.

    nice .venv/bin/python bench/prognosis_cost.py [--fits 10000] [--repeats 15]

A SQLite database (migrated as in service) holds one reference breaker whose fits are written
straight into the fit table: one opening a day, DO 39.5 s^-1 with a 1 % spread leaking 0.002 %
per opening, BO flat. At 1 000, 2 000, 5 000 and 10 000 fits the drift detector is brought up to
date (service.jobs.fit.update_drift, without its prognosis hook) and the worker's prognosis hook,
``store_prognoses`` (read the history, compute, store), is timed ``--repeats`` times: with the
window of the last ``HISTORY_FITS`` fits (what the worker does) and with the whole history since
the reset (what it did before issue 37). Since issue 56 the refresh runs only when due, so it is
timed forced (``force``: the full prognosis), and the per-fit path beside it: one new fit, then
``store_prognoses`` unforced (the calibration's scoring of that fit, issue 55, and the due
check; a refresh when one falls due is counted apart). Writes bench/results/prognosis_cost.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from service.alarms import DriftSettings  # noqa: E402
from service.jobs import prognosis as job  # noqa: E402
from service.storage import crud  # noqa: E402
from service.storage.db import make_engine, session_factory, upgrade  # noqa: E402

RESULTS = ROOT / "bench" / "results" / "prognosis_cost.json"
BREAKER_FILE = ROOT / "config" / "breakers" / "reference-252kV.toml"
T0 = datetime(2020, 1, 1, tzinfo=timezone.utc)


def add_fits(Session, breaker_id: int, lo: int, hi: int, rng) -> None:
    with Session() as s, s.begin():
        for i in range(lo, hi):
            do = 39.5 * (1 + 0.01 * rng.standard_normal()) * (1 - 0.00002 * i)
            bo = 4806.0 * (1 + 0.01 * rng.standard_normal())
            op, _ = crud.create_operation(s, capture_key=f"cost{i}", breaker_id=breaker_id, kind="open",
                                          occurred_at=T0 + timedelta(days=i), source="replay",
                                          capture_path="/nonexistent.csv", capture_sha256="0" * 64, flags=[],
                                          sample_rate=1.0, n_samples=1)
            crud.claim_fit(s, operation_id=op.id, worker="bench")
            crud.store_fit_result(s, operation_id=op.id, curve=None, result={
                "parameters": {"AO": 3424.0, "BO": bo, "DO": do, "EO": 3950.0},
                "ci95": {"DO": [do - 0.4, do + 0.4], "BO": [bo - 40.0, bo + 40.0]}, "identifiable": True})


def timed(Session, breaker_id: int, settings, repeats: int) -> list[float]:
    """The forced refresh of both limited parameters [ms]."""
    out = []
    for _ in range(repeats):
        with Session() as s, s.begin():
            t0 = time.perf_counter()
            job.store_prognoses(s, breaker_id=breaker_id, settings=settings, force={"DO", "BO"})
            out.append((time.perf_counter() - t0) * 1e3)
    return out


def per_fit(Session, breaker_id: int, settings, first: int, repeats: int, rng) -> tuple[list[float], int]:
    """(ms of the unforced hook after each of ``repeats`` new fits when nothing fell due, how many
    fell due): the calibration's scoring and the due check, as the worker runs them per fit."""
    import service.jobs.fit as fitjob

    quiet, due = [], 0
    for i in range(first, first + repeats):
        add_fits(Session, breaker_id, i, i + 1, rng)
        with Session() as s, s.begin():
            fitjob.update_drift(s, breaker_id=breaker_id, settings=settings, prognoses=False)
        with Session() as s, s.begin():
            t0 = time.perf_counter()
            done = job.store_prognoses(s, breaker_id=breaker_id, settings=settings)
            ms = (time.perf_counter() - t0) * 1e3
        if done:
            due += 1
        else:
            quiet.append(ms)
    return quiet, due


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fits", type=int, default=10_000)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--out", type=Path, default=RESULTS)
    a = ap.parse_args(argv)
    import service.jobs.fit as fitjob

    settings = DriftSettings()
    window = job.HISTORY_FITS
    rng = np.random.default_rng(37)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{tmp}/hvcb.sqlite3"
        upgrade(url)
        Session = session_factory(make_engine(url))
        with Session() as s, s.begin():
            b = crud.register_breaker_file(s, path=BREAKER_FILE)
            breaker_id = b.id
        done = 0
        for n in (1000, 2000, 5000, 10_000):
            if n > a.fits:
                break
            add_fits(Session, breaker_id, done, n, rng)
            done = n
            with Session() as s, s.begin():  # the detector alone: the hook is timed below
                fitjob.update_drift(s, breaker_id=breaker_id, settings=settings, prognoses=False)
            row = {"fits": n}
            for name, limit in (("window", window), ("whole_history", 10 ** 9)):
                job.HISTORY_FITS = limit
                ms = timed(Session, breaker_id, settings, a.repeats)
                row[name] = {"median_ms": round(float(np.median(ms)), 1), "p95_ms": round(float(np.percentile(ms, 95)), 1)}
            job.HISTORY_FITS = window
            quiet, due = per_fit(Session, breaker_id, settings, done, a.repeats, rng)
            done += a.repeats
            row["per_fit_not_due"] = ({"median_ms": round(float(np.median(quiet)), 2),
                                       "p95_ms": round(float(np.percentile(quiet, 95)), 2)} if quiet else None)
            row["per_fit_fell_due"] = due
            rows.append(row)
            print(json.dumps(row), flush=True)
    first, last = rows[0], rows[-1]
    result = {"history_fits_window": window, "repeats": a.repeats, "rows": rows,
              "window_p95_ratio_last_first": round(last["window"]["p95_ms"] / first["window"]["p95_ms"], 3),
              "whole_history_p95_ratio_last_first": round(last["whole_history"]["p95_ms"]
                                                          / first["whole_history"]["p95_ms"], 3)}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
