"""Fit latency with the notifier failing against unreachable receivers, against no notifier
(issue 38: "a notifier never blocks a fit or an alarm").

The service as it runs (app factory, local process pool, SQLite or PostgreSQL) takes one upload
at a time; the latency is the wall time from the upload's POST to its fit row being done
(upload, durable capture, queue, fit in the worker, result and drift update stored), and, from
the fit row's own times, queued to done (queue, fit, result and drift update: without the
upload's fsync, whose time on a shared disk varies most). Three conditions, each on a fresh
database:

- ``off``: no notification routes;
- ``failing``: 200 alarm events waiting in the outbox and two routes that cannot deliver them,
  one webhook to a port that refuses connections, one to a "black hole" that accepts the
  connection and never answers (each attempt held for its 2 s timeout), with the default pacing
  (retries from 1 s, doubling);
- ``failing-fast``: the same, retried as fast as the settings allow (50 ms doubling to 200 ms,
  polling every 50 ms): the notifier's worst case.

The conditions take turns (``--rounds``), each round on fresh databases, so a change of the
machine's load (it is shared) spreads over all of them.

    python bench/notify_fit_latency.py [--quick] [--fits 40] [--rounds 4] [--database-url URL]

Writes bench/results/notify_fit_latency.json (``--quick``: ..._quick.json).
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from service.breaker_file import load_breaker  # noqa: E402
from service.settings import load_settings  # noqa: E402
from service.storage.db import upgrade  # noqa: E402
from tests.service.comtrade_bytes import comtrade_pair  # noqa: E402

BREAKER_FILE = REPO / "config" / "breakers" / "reference-252kV.toml"
SECRET = "bench-webhook-secret-0123456789"


def black_hole() -> socket.socket:
    """A listening socket nobody accepts from: connections complete, requests are never answered."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(1024)
    return s


def closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def preload_events(Session, n: int) -> None:
    """n alarm events on a second breaker, stored by the worker's own code path."""
    from sqlalchemy import select

    from service.alarms import AlarmEvent
    from service.jobs.fit import apply_alarm_event
    from service.storage import crud
    from service.storage.models import BreakerRow, utcnow

    with Session() as s, s.begin():
        first = s.scalar(select(BreakerRow).order_by(BreakerRow.id))
        other = crud.upsert_breaker(s, name="bench-bay2", tag="Q2", breaker_file=first.breaker_file,
                                    cam_file_name=first.cam_file_name, cam_table=first.cam_table).id
    kinds = [("raised", "warning"), ("escalated", "alarm"), ("cleared", "alarm")]
    for i in range(n):
        kind, level = kinds[i % 3]
        with Session() as s, s.begin():
            apply_alarm_event(s, breaker_id=other, event=AlarmEvent(kind, "DO", level, i // 3 + 1, None, utcnow(), {}))


PACING = {"off": {}, "failing": {},
          "failing-fast": {"poll_s": 0.05, "retry_min_s": 0.05, "retry_max_s": 0.2, "group_interval_s": 0.0}}


def run(condition: str, fits: int, warmup: int, database_url: str | None, workdir: Path) -> dict:
    from fastapi.testclient import TestClient
    from sqlalchemy import func, select

    from drivers.synthetic import synthesize_capture
    from service.api.app import create_app
    from service.notifications.rows import NotificationDeliveryRow, NotificationEventRow, NotificationRouteRow
    from service.storage.models import FitRow

    hole = black_hole()
    routes = [] if condition == "off" else [
        {"name": "refused", "kind": "webhook", "url": f"http://127.0.0.1:{closed_port()}/h", "secret": SECRET,
         "timeout_s": 2.0},
        {"name": "black-hole", "kind": "webhook", "url": f"http://127.0.0.1:{hole.getsockname()[1]}/h",
         "secret": SECRET, "timeout_s": 2.0}]
    data = workdir / f"{condition}-{len(list(workdir.iterdir()))}"
    url = database_url or f"sqlite:///{data / 'hvcb.sqlite3'}"
    data.mkdir(parents=True)
    upgrade(url)
    settings = load_settings(data_dir=data, database_url=url, broker_url="", executor="local", workers=1,
                             bootstrap_admin_key=None, breakers=[BREAKER_FILE],
                             notifications={"routes": routes, **PACING[condition]})
    breaker = load_breaker(BREAKER_FILE)
    rng = np.random.default_rng(11)
    keys: list[str] = []
    app = create_app(settings, on_key=keys.append)
    latencies, runtimes, in_service = [], [], []
    with TestClient(app) as client:
        Session = app.state.Session
        if routes:
            preload_events(Session, 200)
        h = {"X-API-Key": keys[0]}
        for i in range(warmup + fits):
            p = dict(breaker.design_parameters())
            for k in p:
                p[k] *= 1.0 + rng.normal(0.0, 0.004)
            cap, _ = synthesize_capture(breaker, "open", p, rng=rng)
            cfg, dat = comtrade_pair(cap, name=f"op{i}")
            t0 = time.perf_counter()
            r = client.post("/api/v1/breakers/1/captures", headers=h,
                            files=[("files", (f"op{i}.cfg", cfg)), ("files", (f"op{i}.dat", dat))])
            assert r.status_code in (200, 201, 202), r.text
            while True:
                with Session() as s:
                    done = s.scalar(select(func.count()).select_from(FitRow)
                                    .where(FitRow.status.in_(("done", "failed"))))
                if done >= i + 1:
                    break
                time.sleep(0.01)
            elapsed = time.perf_counter() - t0
            if i >= warmup:
                latencies.append(elapsed)
                with Session() as s:
                    fit = s.scalars(select(FitRow).order_by(FitRow.id.desc()).limit(1)).one()
                    runtimes.append(fit.runtime_s)
                    in_service.append((fit.finished_at - fit.queued_at).total_seconds())
        with Session() as s:
            statuses = dict(s.execute(select(FitRow.status, func.count()).group_by(FitRow.status)).all())
            reasons = sorted({r for r in s.scalars(select(FitRow.failure_reason).where(FitRow.status == "failed"))})
            notifier = {"events": s.scalar(select(func.count()).select_from(NotificationEventRow)),
                        "pending": s.scalar(select(func.count()).select_from(NotificationDeliveryRow)
                                            .where(NotificationDeliveryRow.status == "pending")),
                        "attempts": sum(r.failures for r in s.scalars(select(NotificationRouteRow))),
                        "failures": {r.name: r.failures for r in s.scalars(select(NotificationRouteRow))}}
    hole.close()
    q = statistics.quantiles(latencies, n=10) if len(latencies) >= 2 else latencies * 9
    return {"condition": condition, "fits": len(latencies), "latency_median_s": statistics.median(latencies),
            "latency_p90_s": q[-1], "latency_mean_s": statistics.fmean(latencies),
            "fit_runtime_median_s": statistics.median(runtimes), "queued_to_done_s": in_service, "fit_statuses": statuses, "failure_reasons": reasons,
            "latencies_s": latencies, "notifier": notifier}


def main() -> None:
    import logging

    logging.getLogger("hvcb.notifications").setLevel(logging.ERROR)  # the failing routes' retries, by design
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="6 fits per condition in 2 rounds (development)")
    ap.add_argument("--fits", type=int, default=40, help="fits per condition (over all rounds)")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--database-url", default=None, help="a PostgreSQL server (scratch databases; default: SQLite)")
    args = ap.parse_args()
    fits, rounds = (6, 2) if args.quick else (args.fits, args.rounds)
    per_round = max(1, fits // rounds)
    out = {"database": "postgresql" if args.database_url else "sqlite", "fits_per_condition": per_round * rounds,
           "rounds": rounds, "machine_cores": os.cpu_count(), "conditions": {}}
    runs: dict[str, list[dict]] = {c: [] for c in PACING}
    with tempfile.TemporaryDirectory(prefix="hvcb-notify-bench-") as tmp:
        for r in range(rounds):
            for condition in PACING:
                if args.database_url:
                    from service.storage.scratch import scratch_pg_database

                    with scratch_pg_database(args.database_url, "hvcb_bench") as url:
                        res = run(condition, per_round, 2, url, Path(tmp))
                else:
                    res = run(condition, per_round, 2, None, Path(tmp))
                runs[condition].append(res)
                print(f"round {r + 1} {condition:12s} median {res['latency_median_s']:.3f} s "
                      f"(notifier: {res['notifier']['attempts']} attempts, {res['notifier']['pending']} pending)",
                      flush=True)
    for condition, rs in runs.items():
        lat = [x for r in rs for x in r["latencies_s"]]
        q = statistics.quantiles(lat, n=10)
        qd = [x for r in rs for x in r["queued_to_done_s"]]
        out["conditions"][condition] = {
            "queued_to_done_median_s": statistics.median(qd), "queued_to_done_p90_s": statistics.quantiles(qd, n=10)[-1],
            "latency_median_s": statistics.median(lat), "latency_p90_s": q[-1], "latency_mean_s": statistics.fmean(lat),
            "fit_runtime_median_s": statistics.median(r["fit_runtime_median_s"] for r in rs),
            "fit_statuses": [r["fit_statuses"] for r in rs], "failure_reasons": sorted({x for r in rs for x in r["failure_reasons"]}),
            "notifier": [r["notifier"] for r in rs], "latencies_s": lat, "queued_to_done_s": qd}
    off = out["conditions"]["off"]["latency_median_s"]
    for condition, c in out["conditions"].items():
        c["median_change_s"] = c["latency_median_s"] - off
        c["median_change_rel"] = c["median_change_s"] / off
        c["queued_to_done_change_s"] = c["queued_to_done_median_s"] - out["conditions"]["off"]["queued_to_done_median_s"]
        print(f"{condition:12s} fit latency median {c['latency_median_s']:.3f} s, p90 {c['latency_p90_s']:.3f} s, "
              f"change of the median {c['median_change_s'] * 1000:+.0f} ms ({c['median_change_rel'] * 100:+.1f} %); "
              f"queued to done median {c['queued_to_done_median_s'] * 1000:.0f} ms "
              f"({c['queued_to_done_change_s'] * 1000:+.0f} ms)")
    name = "notify_fit_latency" + ("_quick" if args.quick else "") + ("_postgresql" if args.database_url else "")
    path = REPO / "bench" / "results" / f"{name}.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path.relative_to(REPO)}")


if __name__ == "__main__":
    main()
