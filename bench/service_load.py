"""Service load bench (loopback only, bounded in time).

1. /api/v1/scada/points sustained req/s and p99 latency, one uvicorn worker, SQLite.
2. Time from an operation's end (its capture accepted) to its fit being visible over REST, p95.

Writes bench/results/service_load.json: scada_rps, scada_p99_s, fit_visible_p95_s.
Targets (issue 4): scada_rps >= 500, scada_p99_s <= 0.05, fit_visible_p95_s <= 1.0.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DURATION_S = float(os.environ.get("HVCB_BENCH_SECONDS", "8"))
CLIENTS = 8
OPERATIONS = 12

SERVER = r"""
import sys, uvicorn
from service.settings import load_settings
from service.api.app import create_app
from service.storage.db import upgrade
s = load_settings(data_dir=sys.argv[1], port=int(sys.argv[2]), database_url="", broker_url="", executor="local")
upgrade(s.sqlalchemy_url)
app = create_app(s, on_key=lambda k: print("KEY", k, flush=True))
uvicorn.run(app, host="127.0.0.1", port=s.port, log_level="warning", workers=1)
"""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def scada_load(base: str, key: str) -> tuple[float, float]:
    latencies: list[float] = []
    lock = threading.Lock()
    stop_at = time.perf_counter() + DURATION_S

    def client():
        mine = []
        with httpx.Client(base_url=base, headers={"X-API-Key": key}, timeout=5) as c:
            while time.perf_counter() < stop_at:
                t0 = time.perf_counter()
                r = c.get("/api/v1/scada/points")
                mine.append(time.perf_counter() - t0)
                assert r.status_code == 200, r.text
        with lock:
            latencies.extend(mine)

    t0 = time.perf_counter()
    threads = [threading.Thread(target=client) for _ in range(CLIENTS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    elapsed = time.perf_counter() - t0
    return len(latencies) / elapsed, float(np.percentile(latencies, 99))


def fit_visible(base: str, key: str) -> float:
    sys.path.insert(0, str(ROOT / "tests" / "service"))
    from comtrade_bytes import comtrade_pair

    from drivers.synthetic import synthesize_capture
    from service.breaker_file import load_breaker

    breaker = load_breaker(ROOT / "config" / "breakers" / "reference-252kV.toml")
    rng = np.random.default_rng(1)
    delays = []
    with httpx.Client(base_url=base, headers={"X-API-Key": key}, timeout=30) as c:
        for i in range(OPERATIONS):
            cap, _ = synthesize_capture(breaker, "open", breaker.design_parameters(), rng=rng)
            cfg, dat = comtrade_pair(cap)
            t_end = time.perf_counter()  # the operation's capture is complete: it is sent now
            r = c.post("/api/v1/breakers/1/captures", files=[("files", ("op.cfg", cfg)), ("files", ("op.dat", dat))])
            assert r.status_code == 202, r.text
            op = r.json()["operation_id"]
            while True:
                fit = c.get(f"/api/v1/operations/{op}").json()["fit"]
                if fit["status"] in ("done", "failed"):
                    break
                if time.perf_counter() - t_end > 60:
                    raise RuntimeError("fit not visible after 60 s")
                time.sleep(0.01)
            delays.append(time.perf_counter() - t_end)
            time.sleep(0.2)
    return float(np.percentile(delays[1:], 95))  # the first fit warms the worker


def main() -> int:
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    with tempfile.TemporaryDirectory(prefix="hvcb-bench-") as tmp:
        proc = subprocess.Popen([sys.executable, "-c", SERVER, tmp, str(port)], stdout=subprocess.PIPE, text=True,
                                cwd=ROOT)
        try:
            key = None
            deadline = time.monotonic() + 60
            while key is None and time.monotonic() < deadline:
                line = proc.stdout.readline()
                if line.startswith("KEY "):
                    key = line.split()[1]
            if key is None:
                raise RuntimeError("server did not start")
            while time.monotonic() < deadline:
                try:
                    if httpx.get(base + "/healthz", timeout=1).status_code == 200:
                        break
                except httpx.HTTPError:
                    time.sleep(0.1)
            fit_p95 = fit_visible(base, key)
            rps, p99 = scada_load(base, key)
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
            proc.stdout.close()
    result = {"scada_rps": round(rps, 1), "scada_p99_s": round(p99, 4), "fit_visible_p95_s": round(fit_p95, 3),
              "clients": CLIENTS, "duration_s": DURATION_S, "operations": OPERATIONS}
    out = ROOT / "bench" / "results" / "service_load.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
