"""Heavy work off the API (issue 44 item 2): with 4 condition reports and 2 breaker diagnoses
requested at once while the demo runs, every light route (fleet, breaker, alarms, operations,
keys) keeps p99 <= 300 ms and none times out (10 s); and `hvcb report` takes <= 1.5 x the web
page's report button on the same history.

Starts ``hvcb demo`` (fresh data folder), lets its history play for ``--warm`` s, measures the
light routes alone (baseline), then again while the 4 reports (distinct windows: 4 real jobs)
and 2 diagnoses run, then times the page's button and ``hvcb report`` on the same database.
Writes bench/results/reports_under_load.json.

    flock /tmp/hvcb-heavy.lock nice -n 5 .venv/bin/python bench/reports_under_load.py
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from demo_common import ROOT, Demo  # noqa: E402

TIMEOUT_S = 10.0
LIGHT = {"fleet": "/api/v1/breakers", "breaker": "/api/v1/breakers/1/health", "alarms": "/api/v1/alarms",
         "operations": "/api/v1/breakers/1/operations", "keys": "/api/v1/keys"}


def hammer(url: str, key: str, stop: threading.Event, out: dict, pause_s: float = 0.05) -> None:
    """Each light route in turn, one client, until ``stop``; latency [s] or 'timeout' per request."""
    with httpx.Client(base_url=url, headers={"X-API-Key": key}, timeout=TIMEOUT_S) as c:
        while not stop.is_set():
            for name, path in LIGHT.items():
                t0 = time.perf_counter()
                try:
                    r = c.get(path)
                    out[name].append(time.perf_counter() - t0 if r.status_code < 500 else f"{r.status_code}")
                except httpx.TimeoutException:
                    out[name].append("timeout")
                except httpx.HTTPError as exc:
                    out[name].append(type(exc).__name__)
                time.sleep(pause_s)


def summary(samples: dict) -> dict:
    res = {}
    for name, xs in samples.items():
        t = np.array([x for x in xs if isinstance(x, float)])
        bad = [x for x in xs if not isinstance(x, float)]
        res[name] = {"n": len(xs), "p50_ms": round(float(np.quantile(t, 0.5)) * 1e3, 1) if t.size else None,
                     "p99_ms": round(float(np.quantile(t, 0.99)) * 1e3, 1) if t.size else None,
                     "max_ms": round(float(t.max()) * 1e3, 1) if t.size else None,
                     "failures": len(bad), "failure_kinds": sorted(set(bad))}
    return res


def measure(demo: Demo, seconds: float, clients: int, during=None) -> tuple[dict, dict]:
    samples = {k: [] for k in LIGHT}
    stop = threading.Event()
    threads = [threading.Thread(target=hammer, args=(demo.url, demo.key, stop, samples)) for _ in range(clients)]
    for t in threads:
        t.start()
    extra = {}
    t0 = time.monotonic()
    if during is not None:
        extra = during()
    time.sleep(max(0.0, seconds - (time.monotonic() - t0)))
    stop.set()
    for t in threads:
        t.join()
    return summary(samples), extra


def heavy(demo: Demo) -> dict:
    """4 reports (distinct windows) and 2 diagnoses at once; waits for the reports' PDFs."""
    h = {"X-API-Key": demo.key}
    windows = [{}, {"from": "2000-01-01"}, {"to": "2100-01-01"}, {"from": "2000-01-01", "to": "2100-01-01"}]
    times, codes = [None] * 4, [None] * 4

    def report(i):
        t0 = time.perf_counter()
        with httpx.Client(base_url=demo.url, headers=h, timeout=TIMEOUT_S) as c:
            r = c.get("/api/v1/breakers/1/report", params=windows[i])
            codes[i] = [r.status_code]
            while r.status_code == 202:
                time.sleep(0.5)
                r = c.get(r.headers["Location"])
            codes[i].append(r.status_code)
            times[i] = time.perf_counter() - t0 if r.content[:5] == b"%PDF-" else None

    diag = []
    with httpx.Client(base_url=demo.url, headers=h, timeout=TIMEOUT_S) as c:
        for kind in ("open", "close"):
            t0 = time.perf_counter()
            r = c.post("/api/v1/breakers/1/diagnoses", json={"operation": kind, "last": 5})
            diag.append({"operation": kind, "status": r.status_code, "answered_ms": round((time.perf_counter() - t0) * 1e3, 1)})
    threads = [threading.Thread(target=report, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return {"report_s": [round(t, 2) if t else None for t in times], "report_status": codes, "diagnoses": diag}


def button_time(demo: Demo, repeat: int = 3) -> list[float]:
    out = []
    with httpx.Client(base_url=demo.url, timeout=120) as c:
        form = c.get("/signin")
        token = re.search(r'name="csrf_token" value="([^"]+)"', form.text).group(1)
        c.post("/signin", data={"api_key": demo.key, "csrf_token": token, "next": "/"})
        for _ in range(repeat):
            t0 = time.perf_counter()
            r = c.get("/breakers/1/report.pdf")
            assert r.content[:5] == b"%PDF-", r.text[:200]
            out.append(time.perf_counter() - t0)
    return out


def cli_time(demo: Demo, repeat: int = 3) -> list[float]:
    out = []
    env = {**os.environ, "HVCB_DATA_DIR": str(Path(demo.data_dir) / "demo")}
    for i in range(repeat):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "service.cli", "report", "1", "-o", f"{demo.data_dir}/cli{i}.pdf"],
                       cwd=ROOT, env=env, check=True, capture_output=True)
        out.append(time.perf_counter() - t0)
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--warm", type=float, default=60.0, help="demo history played before measuring [s]")
    ap.add_argument("--seconds", type=float, default=20.0, help="each measuring phase [s]")
    ap.add_argument("--clients", type=int, default=4)
    args = ap.parse_args()
    out = {"uptime_before": os.popen("uptime").read().strip(), "clients": args.clients, "timeout_s": TIMEOUT_S}
    demo = Demo().start()
    try:
        time.sleep(args.warm)
        with httpx.Client(base_url=demo.url, headers={"X-API-Key": demo.key}) as c:
            out["operations_stored"] = len(c.get("/api/v1/breakers/1/operations", params={"limit": 1000}).json())
        out["baseline"], _ = measure(demo, args.seconds, args.clients)
        out["with_4_reports_2_diagnoses"], out["heavy"] = measure(demo, args.seconds, args.clients, lambda: heavy(demo))
        b, c = button_time(demo), cli_time(demo)
        out["page_button_s"], out["hvcb_report_s"] = [round(x, 2) for x in b], [round(x, 2) for x in c]
        out["cli_over_button"] = round(float(np.median(c) / np.median(b)), 2)
    finally:
        demo.stop()
    worst = max(v["p99_ms"] or 0 for v in out["with_4_reports_2_diagnoses"].values())
    out["worst_light_p99_ms_under_load"] = worst
    out["light_failures_under_load"] = sum(v["failures"] for v in out["with_4_reports_2_diagnoses"].values())
    out["uptime_after"] = os.popen("uptime").read().strip()
    (ROOT / "bench" / "results" / "reports_under_load.json").write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
