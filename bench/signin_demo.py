"""200 sign-ins to the web page during the demo's first two minutes (issue 44 item 3: 0 x 5xx).

Starts ``hvcb demo`` in a fresh data folder (its scripted DAQ history, fits and alarms writing to
SQLite meanwhile), then 4 clients sign in 50 times each, spread over 120 s from the moment the
demo answers: GET /signin (the form's one-time token), POST /signin with the demo's admin key.
Writes bench/results/signin_demo.json (status counts, latency quantiles, the demo's database
messages, uptime).

    flock /tmp/hvcb-heavy.lock nice -n 5 .venv/bin/python bench/signin_demo.py
"""

from __future__ import annotations

import json
import os
import re
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import httpx
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from demo_common import ROOT, Demo  # noqa: E402

SIGNINS, CLIENTS, SPAN_S = 200, 4, 120.0


def sign_in(client: httpx.Client, key: str) -> tuple[int, float]:
    t0 = time.perf_counter()
    form = client.get("/signin")
    if form.status_code != 200:
        return form.status_code, time.perf_counter() - t0
    token = re.search(r'name="csrf_token" value="([^"]+)"', form.text).group(1)
    r = client.post("/signin", data={"api_key": key, "csrf_token": token, "next": "/"}, follow_redirects=False)
    return r.status_code, time.perf_counter() - t0


def main() -> int:
    out = {"uptime_before": os.popen("uptime").read().strip(), "signins": SIGNINS, "clients": CLIENTS,
           "span_s": SPAN_S}
    demo = Demo().start()
    statuses: Counter = Counter()
    latencies: list[float] = []
    errors: list[str] = []
    lock = threading.Lock()
    t_start = time.monotonic()

    def client(i: int):
        per = SIGNINS // CLIENTS
        with httpx.Client(base_url=demo.url, timeout=30.0) as c:
            for j in range(per):
                due = t_start + (j + i / CLIENTS) * SPAN_S / per
                time.sleep(max(0.0, due - time.monotonic()))
                try:
                    code, dt = sign_in(c, demo.key)
                except httpx.HTTPError as exc:
                    code, dt = f"network error: {type(exc).__name__}", float("nan")
                with lock:
                    statuses[str(code)] += 1
                    if dt == dt:
                        latencies.append(dt)
                    if not (isinstance(code, int) and code < 500):
                        errors.append(f"{time.monotonic() - demo.started_at:.1f} s: {code}")
                c.cookies.clear()
    try:
        threads = [threading.Thread(target=client, args=(i,)) for i in range(CLIENTS)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        demo.stop()
    lat = np.array(latencies)
    out.update({
        "demo_ready_s": round(demo.ready_s, 2), "statuses": dict(statuses),
        "server_errors": sum(v for k, v in statuses.items() if not k.isdigit() or int(k) >= 500),
        "errors": errors[:20],
        "latency_p50_s": round(float(np.quantile(lat, 0.5)), 3) if lat.size else None,
        "latency_p99_s": round(float(np.quantile(lat, 0.99)), 3) if lat.size else None,
        "latency_max_s": round(float(lat.max()), 3) if lat.size else None,
        "demo_database_messages": demo.database_messages()[:20],
        "uptime_after": os.popen("uptime").read().strip(),
    })
    Path(ROOT / "bench" / "results").mkdir(exist_ok=True)
    (ROOT / "bench" / "results" / "signin_demo.json").write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
