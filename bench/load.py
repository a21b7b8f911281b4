"""Concurrent-reader load bench against `hvcb demo` on 127.0.0.1 (issue 25, D1).

Starts `hvcb demo` as a subprocess on a free port with a fresh data folder, waits until the
emulated DAQ has stored a few fitted operations, signs in once (pages use the session cookie,
API reads the admin key), then for N = 16, 64 and 200 concurrent readers runs 3 waves: in each
wave N readers start at once and each makes 2 requests drawn from a mix of pages and API reads
(fleet page, breaker page, operation page, trends JSON, breaker health, operation list, curve,
a 20,000-point parameter trend). A poller asks /healthz (no key) every 0.2 s throughout.
Bounded: 6 N requests per N, 120 s per request, 900 s in all; the demo is stopped at the end.

Writes bench/results/load.json with, per N: requests/s, p50 and p99 latency [s], the count of
5xx answers, the status counts, and the worst /healthz time [s].
Acceptance (issue 25): no 5xx at N = 200 over 3 waves; /healthz within 2 s throughout.

    .venv/bin/python bench/load.py            # SQLite (the demo's database)
    HVCB_LOAD_DATABASE_URL=postgresql+psycopg://postgres@127.0.0.1:5432/hvcb_load .venv/bin/python bench/load.py
"""

from __future__ import annotations

import asyncio
import json
import os
import random
import re
import signal
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
LEVELS = (16, 64, 200)
WAVES = 3
PER_READER = 2
REQUEST_TIMEOUT_S = 120.0
TOTAL_TIMEOUT_S = 900.0


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def start_demo(data_dir: Path, port: int, log) -> subprocess.Popen:
    env = {**os.environ, "HVCB_DATA_DIR": str(data_dir), "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "service.cli", "demo", "--port", str(port), "--interval", "0.5"]
    db = os.environ.get("HVCB_LOAD_DATABASE_URL")
    if db:
        env["HVCB_DEMO_DATABASE_URL"] = db
    return subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)


def wait_ready(base: str, key_file: Path, proc: subprocess.Popen, timeout_s: float = 180.0) -> str:
    """The admin key once the demo has at least 6 fitted operations."""
    deadline = time.monotonic() + timeout_s
    key = None
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError("the demo exited early (see its log)")
        try:
            if key is None and key_file.is_file():
                key = key_file.read_text().strip()
            if key:
                ops = httpx.get(f"{base}/api/v1/breakers/1/operations?limit=50", headers={"X-API-Key": key},
                                timeout=5).json()
                if sum(1 for o in ops if (o.get("fit") or {}).get("status") == "done") >= 6:
                    return key
        except (httpx.HTTPError, ValueError):
            pass
        time.sleep(1.0)
    raise RuntimeError("the demo did not store 6 fitted operations within the time limit")


def sign_in(base: str, key: str) -> dict:
    with httpx.Client(base_url=base, timeout=10) as c:
        form = c.get("/signin").text
        csrf = re.search(r'name="csrf_token" value="([^"]+)"', form).group(1)
        r = c.post("/signin", data={"api_key": key, "csrf_token": csrf, "next": "/"}, follow_redirects=False)
        assert r.status_code == 303, r.text
        return dict(c.cookies)


def request_mix(op_ids: list[int]) -> list[tuple[str, str]]:
    """(kind, path): pages with the cookie, api with the key."""
    op = op_ids[len(op_ids) // 2]
    return [("page", "/"), ("page", "/breakers/1"), ("page", f"/operations/{op}"),
            ("page", "/ui/breakers/1/trends.json"), ("api", "/api/v1/breakers/1/health"),
            ("api", "/api/v1/breakers/1/operations?limit=50"), ("api", f"/api/v1/operations/{op}/curve"),
            ("api", "/api/v1/breakers/1/parameters?name=DO&limit=20000")]


async def run_level(base: str, key: str, cookies: dict, mix: list, n: int, rng: random.Random) -> dict:
    latencies, statuses = [], {}
    retried = [0]
    worst_health = 0.0
    stop = threading.Event()
    # idle connections dropped by the client before the server's 5 s keep-alive closes them (no reuse race)
    limits = httpx.Limits(max_connections=n + 8, max_keepalive_connections=n + 8, keepalive_expiry=2.0)

    def health_poller():  # its own thread and connection: the readers' event loop does not delay it
        nonlocal worst_health
        with httpx.Client(base_url=base, timeout=30) as hc:
            while not stop.is_set():
                t0 = time.perf_counter()
                try:
                    ok = hc.get("/healthz").status_code == 200
                except httpx.HTTPError:
                    ok = False
                dt = time.perf_counter() - t0
                worst_health = max(worst_health, dt if ok else float("inf"))
                time.sleep(0.2)

    async with httpx.AsyncClient(base_url=base, timeout=REQUEST_TIMEOUT_S, limits=limits) as api, \
            httpx.AsyncClient(base_url=base, timeout=REQUEST_TIMEOUT_S, limits=limits, cookies=cookies) as web:
        async def reader(picks):
            for kind, path in picks:
                t0 = time.perf_counter()
                code = None
                for attempt in range(2):
                    try:
                        if kind == "api":
                            r = await api.get(path, headers={"X-API-Key": key})
                        else:
                            r = await web.get(path)
                        code = r.status_code
                        break
                    except (httpx.RemoteProtocolError, httpx.ReadError) as exc:
                        # a kept-alive connection the server closed as we reused it: a GET may be
                        # sent again on a fresh one (RFC 9112 9.3.1; browsers do); counted
                        code = f"error:{type(exc).__name__}"
                        if attempt == 0:
                            retried[0] += 1
                    except httpx.HTTPError as exc:
                        code = f"error:{type(exc).__name__}"
                        break
                latencies.append(time.perf_counter() - t0)
                statuses[str(code)] = statuses.get(str(code), 0) + 1

        poller = threading.Thread(target=health_poller, daemon=True)
        poller.start()
        t_start = time.perf_counter()
        for _ in range(WAVES):
            await asyncio.gather(*(reader([rng.choice(mix) for _ in range(PER_READER)]) for _ in range(n)))
        elapsed = time.perf_counter() - t_start
        stop.set()
        poller.join()
    lat = np.asarray(latencies)
    n5xx = sum(v for k, v in statuses.items() if k.startswith("5") or k.startswith("error"))
    return {"readers": n, "waves": WAVES, "requests": int(lat.size), "seconds": round(elapsed, 2),
            "requests_per_s": round(lat.size / elapsed, 1), "p50_s": round(float(np.percentile(lat, 50)), 3),
            "p99_s": round(float(np.percentile(lat, 99)), 3), "count_5xx": int(n5xx), "statuses": statuses,
            "worst_healthz_s": round(worst_health, 3), "retried_on_closed_connection": retried[0]}


async def bench(base: str, key: str) -> list[dict]:
    cookies = sign_in(base, key)
    ops = httpx.get(f"{base}/api/v1/breakers/1/operations?limit=50", headers={"X-API-Key": key}, timeout=10).json()
    mix = request_mix(sorted(o["id"] for o in ops))
    rng = random.Random(25)
    out = []
    for n in LEVELS:
        row = await run_level(base, key, cookies, mix, n, rng)
        print(f"N={n:4d}  {row['requests']:5d} req  {row['requests_per_s']:7.1f} req/s  p50 {row['p50_s']:6.3f} s  "
              f"p99 {row['p99_s']:6.3f} s  5xx {row['count_5xx']:4d}  worst /healthz {row['worst_healthz_s']:.3f} s  "
              f"{row['statuses']}  retried {row['retried_on_closed_connection']}", flush=True)
        out.append(row)
    return out


def main() -> int:
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    log_path = Path(os.environ.get("HVCB_LOAD_LOG", ROOT / "bench" / "results" / "load_server.log"))
    with tempfile.TemporaryDirectory(prefix="hvcb-load-") as tmp, open(log_path, "w") as log:
        proc = start_demo(Path(tmp), port, log)
        try:
            key = wait_ready(base, Path(tmp) / "demo" / "admin.key", proc)
            rows = asyncio.run(asyncio.wait_for(bench(base, key), TOTAL_TIMEOUT_S))
        finally:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
    server_log = log_path.read_text(errors="replace")
    tracebacks = server_log.count("Traceback")
    print(f"server log {log_path}: {tracebacks} tracebacks")
    result = {"database": "postgresql" if os.environ.get("HVCB_LOAD_DATABASE_URL") else "sqlite",
              "server": "hvcb demo, one uvicorn worker, [server] defaults", "levels": rows,
              "server_tracebacks": tracebacks,
              "acceptance": {"no_5xx_at_200": rows[-1]["count_5xx"] == 0,
                             "healthz_within_2s": all(r["worst_healthz_s"] <= 2.0 for r in rows)}}
    out = ROOT / "bench" / "results" / "load.json"
    name = out if result["database"] == "sqlite" else out.with_name("load_postgresql.json")
    name.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {name.relative_to(ROOT)}: {result['acceptance']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
