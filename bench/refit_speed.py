"""Refit throughput: fits per second for stored operations, half openings and half closings.

Stores a history of N operations (default 2000) of one breaker, each with a finished fit, then
re-fits all of them twice: once on the local process pool (--workers, default 2) and once
through Celery on Redis (a ``celery worker`` subprocess with the same concurrency), when a
broker is given. Each run is timed from the command's start to its last landed batch, pool
start-up included. The CPU figure is the workers' CPU time per fit (their rusage), i.e. the
rate the pool would reach with a core per worker; the wall figure is what this machine gave,
which other load on it lowers. Writes bench/results/refit_speed.json.

    python bench/refit_speed.py [--operations 2000] [--workers 2] [--batch-size 25]
        [--database-url postgresql+psycopg://...] [--broker redis://127.0.0.1:6379/4]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from service.breaker_file import load_breaker  # noqa: E402
from service.jobs.fit import JobOptions  # noqa: E402
from service.refit import pool  # noqa: E402
from service.refit.runs import run_refit, start_run  # noqa: E402
from service.settings import load_settings  # noqa: E402
from service.storage.db import make_engine, session_factory, upgrade  # noqa: E402
from tests.refit.fleet import seed_history  # noqa: E402


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _timed_run(Session, submit, options, batch_size):
    with Session() as s, s.begin():
        run_id = start_run(s, requested_by="bench")[0].id
    first = {}

    def on_progress(n, total):
        if n and "t" not in first:
            first["t"] = time.perf_counter()

    t0 = time.perf_counter()
    run = run_refit(Session, run_id, submit_batches=submit, options=options, on_progress=on_progress,
                    batch_size=batch_size)
    wall = time.perf_counter() - t0
    return run, wall, first.get("t", t0) - t0


def _start_celery_worker(env, concurrency, log_path):
    log = open(log_path, "ab")
    proc = subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "service.workers.celery_app", "worker", "--pool=prefork",
         f"--concurrency={concurrency}", "--without-gossip", "--without-mingle", "--without-heartbeat",
         "--loglevel=INFO", "-n", f"bench-{uuid.uuid4().hex[:6]}@%h"],
        cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise SystemExit(f"celery worker exited: see {log_path}")
        if " ready." in Path(log_path).read_text(errors="replace"):
            return proc
        time.sleep(0.2)
    raise SystemExit(f"celery worker not ready: see {log_path}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--operations", type=int, default=2000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--batch-size", type=int, default=25)
    ap.add_argument("--database-url", default=None, help="default: a fresh SQLite file")
    ap.add_argument("--broker", default=os.environ.get("HVCB_BENCH_BROKER_URL"),
                    help="Redis URL for the Celery figure (skipped without one)")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="hvcb-refit-bench-"))
    url = args.database_url or f"sqlite:///{tmp / 'hvcb.sqlite3'}"
    if args.database_url and url.startswith("postgresql"):
        from sqlalchemy import text

        eng = make_engine(url)
        with eng.begin() as conn:  # a bench database: start from an empty schema
            conn.execute(text("DROP SCHEMA public CASCADE"))
            conn.execute(text("CREATE SCHEMA public"))
        eng.dispose()
    upgrade(url)
    engine = make_engine(url)
    Session = session_factory(engine)
    breaker = load_breaker(REPO / "config" / "breakers" / "reference-252kV.toml")
    t0 = time.perf_counter()
    seed_history(Session, breaker, tmp / "captures", args.operations, per_kind=3)
    print(f"stored {args.operations} operations with fits in {time.perf_counter() - t0:.1f} s "
          f"({url.split('@')[-1].split('///')[0]})", flush=True)
    options = JobOptions(database_url=url)
    results = {"operations": args.operations, "workers": args.workers, "batch_size": args.batch_size,
               "database": url.split(":")[0], "load_average_at_start": list(os.getloadavg()),
               "cpu_count": os.cpu_count()}

    cpu0, batch_cpu = _children_cpu(), []
    run, wall, first = _timed_run(
        Session, pool.local_pool(options, args.workers, on_batch=lambda r: batch_cpu.append(r["cpu_s"])),
        options, args.batch_size)
    cpu = _children_cpu() - cpu0
    n = run.done + run.failed
    per_fit = sum(batch_cpu) / n
    results.update(local_fits=n, local_failed=run.failed, local_wall_s=wall,
                   local_fits_per_s_wall=n / wall, local_first_batch_s=first,
                   local_cpu_per_fit_s=per_fit, local_fits_per_s_cpu=args.workers / per_fit,
                   local_worker_cpu_with_startup_s=cpu)
    print(f"local pool ({args.workers} workers): {n} fits in {wall:.1f} s wall = {n / wall:.0f} fits/s "
          f"(first batch after {first:.1f} s); {per_fit * 1e3:.1f} ms CPU per fit = "
          f"{args.workers / per_fit:.0f} fits/s with a core per worker (workers' CPU with start-up "
          f"{cpu:.1f} s)", flush=True)

    if args.broker:
        queue = f"bench-refit-{uuid.uuid4().hex[:6]}"
        env = {k: v for k, v in os.environ.items() if not k.startswith("HVCB_") and k != "DATABASE_URL"}
        env.update(HVCB_BROKER_URL=args.broker, DATABASE_URL=url, HVCB_DATA_DIR=str(tmp / "data"),
                   HVCB_CELERY_QUEUE=queue, HVCB_CELERY_KEY_PREFIX=queue + ":", PYTHONPATH=str(REPO),
                   NUMBA_NUM_THREADS="1")
        worker = _start_celery_worker(env, args.workers, tmp / "celery.log")
        try:
            settings = load_settings(None, data_dir=tmp / "data", database_url=url, broker_url=args.broker,
                                     celery_queue=queue, celery_key_prefix=queue + ":")
            run, wall, first = _timed_run(Session, pool.celery(settings, Session, timeout_s=1800), options,
                                          args.batch_size)
        finally:
            os.killpg(worker.pid, 15)
            worker.wait(timeout=60)
        n = run.done + run.failed
        results.update(celery_fits=n, celery_failed=run.failed, celery_wall_s=wall,
                       celery_fits_per_s_wall=n / wall, celery_first_batch_s=first)
        print(f"celery ({args.workers} worker processes): {n} fits in {wall:.1f} s wall = "
              f"{n / wall:.0f} fits/s", flush=True)
    results["load_average_at_end"] = list(os.getloadavg())
    engine.dispose()
    out = REPO / "bench" / "results" / "refit_speed.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
