"""Edge-agent ingest bench (loopback only, bounded in count and time).

One central hvcb (`hvcb serve` shape: uvicorn, fit pool of 2 workers; SQLite, or PostgreSQL with
--database-url) receives captures from 10 simulated edge agents. Each agent is the real agent
code minus the DAQ: an Outbox of durable COMTRADE captures and a Forwarder posting them with an
`agent` key and an Idempotency-Key, one breaker per agent.

1. Burst: every agent has PER_AGENT captures waiting at once (a WAN back after an outage).
   Figures: captures/s accepted by the upload API, captures/s fitted (upload → fit visible
   over REST), p95 capture → visible fit.
2. Steady: the agents together produce captures at a quarter of the fitted rate measured in 1
   (well below capacity even when the shared machine gets busier).
   Figure: p95 capture → visible fit at that load.

"Visible" = the first poll of GET /api/v1/breakers/{id}/operations showing the fit done or
failed (polled every 0.1 s). Writes bench/results/agent_throughput.json.

    .venv/bin/python bench/agent_throughput.py [--per-agent 6] [--database-url postgresql+psycopg://...]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
AGENTS = 10
WORKERS = 2
POLL_S = 0.1


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def breaker_files(directory: Path, n: int) -> list[Path]:
    ref = ROOT / "config" / "breakers" / "reference-252kV.toml"
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "reference-252kV.cam.csv").write_text(ref.with_name("reference-252kV.cam.csv").read_text())
    out = []
    for i in range(n):
        p = directory / f"bay{i + 1:02d}.toml"
        p.write_text(ref.read_text().replace('name = "reference-252kV"', f'name = "bay{i + 1:02d}"'))
        out.append(p)
    return out


def start_central(tmp: Path, port: int, breakers: list[Path], database_url: str) -> subprocess.Popen:
    cfg = tmp / "central.toml"
    lines = [f'data_dir = "{tmp / "central"}"', f"port = {port}", f"workers = {WORKERS}", 'executor = "local"',
             "breakers = [" + ", ".join(f'"{p}"' for p in breakers) + "]"]
    cfg.write_text("\n".join(lines) + "\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "DATABASE_URL": database_url, "HVCB_BROKER_URL": ""}
    proc = subprocess.Popen([sys.executable, "-m", "service.cli", "serve", "--config", str(cfg)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=1).status_code == 200:
                return proc
        except httpx.HTTPError:
            time.sleep(0.2)
        if proc.poll() is not None:
            raise SystemExit(f"the central server did not start:\n{proc.stdout.read()}")
    raise SystemExit("the central server did not answer within 120 s")


class SimAgent:
    """One agent: its own outbox, forwarder and breaker; captures made ahead of time."""

    def __init__(self, i: int, tmp: Path, breaker, central, *, captures: int, seed: int, on_sent):
        from service.acquisition.comtrade_writer import write_comtrade
        from drivers.synthetic import synthesize_capture
        from service.agent.forwarder import Forwarder
        from service.agent.outbox import Outbox

        self.dir = tmp / f"agent{i:02d}"
        self.outbox = Outbox(self.dir / "outbox", self.dir / "captures", max_bytes=10 ** 10)
        self.staged = []
        rng = np.random.default_rng(seed)
        p = dict(breaker.design_parameters())
        for k in range(captures):
            cap, _ = synthesize_capture(breaker, "open", {n: v * (1 + rng.normal(0, 0.004)) for n, v in p.items()},
                                        rng=rng)
            self.staged.append(write_comtrade(cap, self.dir / "staged", f"op-{k:04d}-open"))
        self.breaker = breaker.name
        self.forwarder = Forwarder(self.outbox, central, on_sent=on_sent)

    def capture(self) -> None:
        """The next staged capture is 'captured' now: moved into place and journalled."""
        cfg = self.staged.pop(0)
        dest = self.dir / "captures" / self.breaker
        dest.mkdir(parents=True, exist_ok=True)
        for suffix in (".cfg", ".dat", ".hdr"):
            src = cfg.with_suffix(suffix)
            if src.exists():
                os.replace(src, dest / src.name)
        self.outbox.put(dest / cfg.name, breaker=self.breaker, operation="open",
                        captured_at=datetime.now(timezone.utc))


class Tracker:
    """Follows operations from upload to a visible fit."""

    def __init__(self, base: str, key: str, breaker_ids: dict[str, int]):
        self.client = httpx.Client(base_url=base, headers={"X-API-Key": key}, timeout=10)
        self.breaker_ids = breaker_ids
        self.captured: dict[int, float] = {}   # operation id -> captured (epoch s)
        self.accepted: dict[int, float] = {}   # operation id -> upload answered (epoch s)
        self.visible: dict[int, float] = {}    # operation id -> fit seen done/failed (epoch s)
        self.lock = threading.Lock()

    def on_sent(self, entry, body) -> None:
        with self.lock:
            op = body["operation_id"]
            if op is not None:
                self.captured[op] = entry.captured.timestamp()
                self.accepted[op] = time.time()

    def poll_until(self, n: int, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            now = time.time()
            for bid in self.breaker_ids.values():
                for op in self.client.get(f"/api/v1/breakers/{bid}/operations", params={"limit": 1000}).json():
                    fit = op.get("fit") or {}
                    if fit.get("status") in ("done", "failed") and op["id"] not in self.visible:
                        self.visible[op["id"]] = now
            with self.lock:
                if len([o for o in self.captured if o in self.visible]) >= n:
                    return
            time.sleep(POLL_S)
        raise SystemExit(f"only {len(self.visible)} of {n} fits visible after {timeout} s")

    def latencies(self, ops) -> np.ndarray:
        return np.array([self.visible[o] - self.captured[o] for o in ops])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-agent", type=int, default=6, help="burst captures per agent")
    ap.add_argument("--steady-s", type=float, default=20.0, help="length of the steady phase [s]")
    ap.add_argument("--database-url", default="", help="central database (default SQLite in a temp dir)")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "agent_throughput.json"))
    args = ap.parse_args()
    import logging

    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("httpx").setLevel(logging.WARNING)

    from service.agent.settings import CentralSettings
    from service.breaker_file import load_breaker

    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="hvcb-agent-bench-") as tmpdir:
        tmp = Path(tmpdir)
        files = breaker_files(tmp / "breakers", AGENTS)
        port = free_port()
        central_proc = start_central(tmp, port, files, args.database_url)
        base = f"http://127.0.0.1:{port}"
        try:
            admin = (tmp / "central" / "admin.key").read_text().strip()
            h = {"X-API-Key": admin}
            key = httpx.post(f"{base}/api/v1/keys", headers=h, json={"name": "bench", "role": "agent"}).json()["key"]
            ids = {b["name"]: b["id"] for b in httpx.get(f"{base}/api/v1/breakers", headers=h).json()}
            central = CentralSettings(url=base, api_key=key, breaker_ids=ids, retry_min_s=0.2, retry_max_s=2.0)
            tracker = Tracker(base, admin, ids)
            breakers = [load_breaker(f) for f in files]
            steady_each = max(1, int(np.ceil(args.steady_s / 10)))  # enough staged for the steady phase
            print(f"making {AGENTS} x {args.per_agent + steady_each * 4 + 1} captures ...", flush=True)
            agents = [SimAgent(i, tmp, breakers[i], central, captures=args.per_agent + steady_each * 4 + 1,
                               seed=100 + i, on_sent=tracker.on_sent) for i in range(AGENTS)]
            for a in agents:
                a.forwarder.start()

            # warm-up: one capture per agent (compiles the kernels in both fit workers)
            for a in agents:
                a.capture()
            tracker.poll_until(AGENTS, 300)
            warm = set(tracker.captured)

            # 1. burst
            print(f"burst: {AGENTS} agents x {args.per_agent} captures", flush=True)
            t0 = time.time()
            for a in agents:
                for _ in range(args.per_agent):
                    a.capture()
            n_burst = AGENTS * args.per_agent
            tracker.poll_until(len(warm) + n_burst, 600)
            burst = [o for o in tracker.captured if o not in warm]
            accepted_s = max(tracker.accepted[o] for o in burst) - t0
            visible_s = max(tracker.visible[o] for o in burst) - t0
            burst_lat = tracker.latencies(burst)
            upload_rate, fit_rate = n_burst / accepted_s, n_burst / visible_s

            # 2. steady load at a quarter of the fitted rate
            rate = fit_rate / 4
            interval = 1.0 / rate
            n_steady = min(int(args.steady_s * rate), sum(len(a.staged) for a in agents))
            print(f"steady: {rate:.2f} captures/s for {n_steady} captures", flush=True)
            before = set(tracker.captured)
            follow = threading.Thread(target=tracker.poll_until, args=(len(before) + n_steady, 300))
            follow.start()  # fits are seen as they become visible, not after the last capture
            start = time.monotonic()
            for k in range(n_steady):
                agents[k % AGENTS].capture()
                time.sleep(max(0.0, start + (k + 1) * interval - time.monotonic()))
            follow.join()
            tracker.poll_until(len(before) + n_steady, 300)
            steady = [o for o in tracker.captured if o not in before]
            steady_lat = tracker.latencies(steady)

            for a in agents:
                a.forwarder.stop()
            duplicates = sum(a.forwarder.duplicates for a in agents)
        finally:
            central_proc.terminate()
            try:
                central_proc.wait(30)
            except subprocess.TimeoutExpired:
                central_proc.kill()

    result = {
        "agents": AGENTS, "fit_workers": WORKERS,
        "database": "postgresql" if args.database_url.startswith("postgresql") else "sqlite",
        "cpu_cores": os.cpu_count(),
        "load_average_1min_before_after": [round(load_before, 1), round(os.getloadavg()[0], 1)],
        "burst_captures": n_burst,
        "burst_upload_captures_per_s": round(upload_rate, 2),
        "burst_fitted_captures_per_s": round(fit_rate, 2),
        "burst_capture_to_visible_fit_p50_s": round(float(np.percentile(burst_lat, 50)), 2),
        "burst_capture_to_visible_fit_p95_s": round(float(np.percentile(burst_lat, 95)), 2),
        "steady_rate_captures_per_s": round(rate, 2),
        "steady_captures": n_steady,
        "steady_capture_to_visible_fit_p50_s": round(float(np.percentile(steady_lat, 50)), 2),
        "steady_capture_to_visible_fit_p95_s": round(float(np.percentile(steady_lat, 95)), 2),
        "duplicate_answers": duplicates,
        "note": "wall time on a shared machine; the fit (CPU) bounds the fitted rate, the upload path does not",
    }
    print(json.dumps(result, indent=1))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
