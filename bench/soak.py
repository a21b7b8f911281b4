"""Endurance run of the whole chain at accelerated speed (issue 15).

    python bench/soak.py --operations 10000 --breakers 4
    python bench/soak.py --operations 2000 --database postgresql+psycopg://postgres@127.0.0.1/postgres --celery

One Modbus TCP DAQ emulator per breaker (in this process) serves the scripted history; a real
``hvcb serve`` (a subprocess, with its fit pool or Celery workers) downloads each capture, runs
the trigger, writes the COMTRADE file, stores the operation, fits it and updates the drift
alarms. Breaker 1 leaks buffer oil (DO falling), breaker 2's opening spring relaxes (BO
falling), the others are controls. Among the operations the DAQs also deliver decoys (a shock
with no motion, a burst of interference) and a few faulty replies (exception responses, a late
reply past the driver's timeout), which the driver must retry without losing or doubling a
capture. Each DAQ delivers its next operation once the previous capture is acknowledged and
at most ``--max-pending`` fits are waiting, so the run goes as fast as the service keeps up.

Each operation is traced by its stream position (the sample index the DAQ reports, written in
the COMTRADE .hdr): lost = scripted operations never stored, duplicated = stored twice.
Fit-visible time: from the capture being handed to the DAQ to its fit row committed (the API
shows it from then on). RSS: the service process (and its fit workers) after the first tenth
of the operations and at the end.

Writes bench/results/soak.json (or --out). PostgreSQL: a fresh database is created on the
server of --database and dropped afterwards (unless --keep).
"""

from __future__ import annotations

import argparse
import contextlib
import asyncio
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from service.storage.scratch import scratch_pg_database  # noqa: E402
from soak_scenario import (DECOY_EVERY, FAULT_EVERY, FS, LATE_EVERY, BreakerScript,  # noqa: E402
                           breaker_files, judge_alarms)

ADMIN_KEY = "soak-bench-admin-key-" + uuid.uuid4().hex


def quiet_modbus() -> None:
    import logging

    for name in ("pymodbus", "pymodbus.logging"):
        logging.getLogger(name).setLevel(logging.ERROR)


def log(msg: str) -> None:
    print(f"[{datetime.now(timezone.utc):%H:%M:%S}] {msg}", flush=True)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# -- the DAQs ------------------------------------------------------------------------------------
class Daqs:
    """One Modbus TCP DAQ emulator per breaker on an event loop thread, fed with backpressure."""

    def __init__(self, scripts, pending_fits, max_pending: int, *, fault_every: int = FAULT_EVERY,
                 on_temperature=None):
        self.scripts, self.pending_fits, self.max_pending = scripts, pending_fits, max_pending
        self.fault_every = fault_every
        self.on_temperature = on_temperature  # (breaker name, °C) before each capture, or None
        self.emulators = []
        self.ports: list[int] = []
        self.handed: list[list[tuple]] = [[] for _ in scripts]  # (first_sample_index, n, kind, t_handed)
        self.faults = {"exception_responses": 0, "late_replies": 0}
        self.done = threading.Event()
        self.error: BaseException | None = None
        self._ready = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="soak-daqs", daemon=True)

    def start(self) -> list[int]:
        self._thread.start()
        if not self._ready.wait(60) or self.error:
            raise RuntimeError(f"DAQ emulators did not start: {self.error}")
        return self.ports

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(30)

    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as exc:
            self.error = exc
            self._ready.set()
            log(f"DAQ emulators failed: {exc!r}")

    async def _main(self) -> None:
        from drivers.emulators.modbus_daq import ModbusDaqEmulator
        from drivers.scaling import ChannelScaling

        for s in self.scripts:
            em = ModbusDaqEmulator([], transport="tcp", host="127.0.0.1", port=0,
                                   scaling=ChannelScaling.from_breaker(s.breaker))
            await em.start()
            self.emulators.append(em)
            self.ports.append(em.port)
        self._ready.set()
        try:
            await asyncio.gather(*(self._feed(i) for i in range(len(self.scripts))))
            self.done.set()
            while not self._stop.is_set():
                await asyncio.sleep(0.2)
        finally:
            for em in self.emulators:
                await em.stop()

    async def _feed(self, i: int) -> None:
        from drivers.interface import SampleBlock

        em, script = self.emulators[i], self.scripts[i]
        items = script.items()
        index, added, rng = 0, 0, np.random.default_rng(100 + i)
        while not self._stop.is_set():
            item = await asyncio.to_thread(next, items, None)
            if item is None:
                return
            kind, travel, vib, temperature = item
            # the DAQ is free (last capture acknowledged) and the service is keeping up
            while not self._stop.is_set() and (em.stats.captures_acknowledged < added
                                               or self.pending_fits() >= self.max_pending):
                await asyncio.sleep(0.005)
            if temperature is not None and self.on_temperature is not None:
                await asyncio.to_thread(self.on_temperature, script.breaker.name, temperature)
            if added and added % self.fault_every == 0:
                em.inject_exception(at_read=int(rng.integers(2, 60)))
                self.faults["exception_responses"] += 1
            if added and added % LATE_EVERY == 0:
                em.inject_delay(1.5, at_read=int(rng.integers(2, 60)))
                self.faults["late_replies"] += 1
            em.add_capture(SampleBlock(index, travel, vib, FS))
            self.handed[i].append((index, travel.size, kind, time.time()))
            em.served.clear()  # the emulator keeps every capture for tests; a soak must not
            added += 1
            index += travel.size + int(FS)  # a second of stream between captures


# -- the service ---------------------------------------------------------------------------------
def write_config(tmp: Path, files: list[Path], ports: list[int], args, database_url: str | None,
                 port: int) -> Path:
    from service.breaker_file import load_breaker

    lines = [f'data_dir = "{tmp / "data"}"', 'host = "127.0.0.1"', f"port = {port}",
             f"breakers = {json.dumps([str(f) for f in files])}", f"workers = {args.workers}",
             f'bootstrap_admin_key = "{ADMIN_KEY}"', "spool_retry_s = 1.0",
             f'celery_queue = "hvcb-soak-{os.getpid()}"', f'celery_key_prefix = "hvcb-soak-{os.getpid()}:"']
    if database_url:
        lines.append(f'database_url = "{database_url}"')
    if args.celery:
        lines += ['executor = "celery"', f'broker_url = "{args.redis}"']
    else:
        lines += ['executor = "local"', 'broker_url = ""']
    lines += ["", "[alarms]", "baseline_n = 20", "[alarms.watched]", 'DO = "falling"', 'BO = "both"']
    for f, p in zip(files, ports):
        name = load_breaker(f).name
        lines += ["", "[[acquisition]]", 'driver = "modbus"', f'breaker = "{name}"', f'name = "{name}-daq"',
                  "status_interval_s = 2.0", "[acquisition.modbus]", 'transport = "tcp"', 'host = "127.0.0.1"',
                  f"port = {p}", "poll_interval_s = 0.02", "timeout_s = 1.0", "block_retries = 3"]
    cfg = tmp / "soak.toml"
    cfg.write_text("\n".join(lines) + "\n")
    return cfg


def rss_mb(pid: int) -> float:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def children(pid: int) -> list[int]:
    out = []
    for p in Path("/proc").iterdir():
        if p.name.isdigit():
            try:
                if int((p / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                    out.append(int(p.name))
            except (OSError, IndexError, ValueError):
                continue
    return out


def db_bytes(url: str, engine, data_dir: Path) -> int:
    if url.startswith("sqlite"):  # the database file; its WAL is bounded by checkpoints
        return (data_dir / "hvcb.sqlite3").stat().st_size
    from sqlalchemy import text

    with engine.connect() as c:
        return int(c.scalar(text("SELECT pg_database_size(current_database())")))


# -- the run -------------------------------------------------------------------------------------
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--operations", type=int, default=200, help="real operations over all breakers")
    ap.add_argument("--breakers", type=int, default=4)
    ap.add_argument("--database", default=None, help="PostgreSQL server URL (a fresh database is made on it); "
                                                     "default SQLite")
    ap.add_argument("--celery", action="store_true", help="Celery fit workers (needs --redis)")
    ap.add_argument("--redis", default=os.environ.get("HVCB_SOAK_REDIS_URL", "redis://127.0.0.1:6379/5"))
    ap.add_argument("--workers", type=int, default=1, help="fit workers (pool size, or Celery worker processes)")
    ap.add_argument("--max-pending", type=int, default=3, help="the DAQs wait while this many fits are pending")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "soak.json"))
    ap.add_argument("--keep", action="store_true", help="keep the data directory and database")
    ap.add_argument("--seed", type=int, default=15)
    ap.add_argument("--decoy-every", type=int, default=DECOY_EVERY, help="one DAQ capture in N is a decoy")
    ap.add_argument("--fault-every", type=int, default=FAULT_EVERY,
                    help="one download in N gets an exception response")
    ap.add_argument("--temperature", choices=("off", "given", "hidden"), default="off",
                    help="seasonal temperature profile: off; on and reported to the service (SCADA writes "
                         "it over REST before each operation); on but never reported")
    args = ap.parse_args(argv)
    quiet_modbus()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # stop the service and workers too
    if args.breakers < 1 or args.operations < args.breakers:
        ap.error("need at least one breaker and one operation per breaker")

    from sqlalchemy import func, select

    from service.breaker_file import load_breaker
    from service.storage.db import make_engine
    from service.storage.models import FitRow, OperationRow

    tmp = Path(tempfile.mkdtemp(prefix="hvcb-soak-"))
    files = breaker_files(tmp, args.breakers)
    per = [args.operations // args.breakers + (1 if i < args.operations % args.breakers else 0)
           for i in range(args.breakers)]
    scripts = [BreakerScript(load_breaker(f), i, per[i], args.seed + i, decoy_every=args.decoy_every,
                             seasons=args.temperature != "off") for i, f in enumerate(files)]
    scratch = contextlib.ExitStack()  # the fresh PostgreSQL database, dropped at the end
    database_url = scratch.enter_context(scratch_pg_database(args.database, prefix="hvcb_soak")) \
        if args.database else None
    url = database_url or f"sqlite:///{(tmp / 'data' / 'hvcb.sqlite3').resolve()}"
    engine = None
    procs: list[subprocess.Popen] = []
    state = {"pending": 0}
    service_url = {}
    service_up = threading.Event()

    def report_temperature(breaker: str, celsius: float) -> None:
        import httpx

        if not service_up.wait(180):
            raise RuntimeError("the service did not come up: no temperature can be written")
        r = httpx.put(f"{service_url['base']}/api/v1/breakers/{breaker}/temperature",
                      json={"temperature_c": round(celsius, 2)}, headers={"X-API-Key": ADMIN_KEY}, timeout=30)
        if r.status_code >= 300:
            raise RuntimeError(f"the service refused the temperature of {breaker}: {r.status_code} {r.text[:200]}")

    daqs = Daqs(scripts, lambda: state["pending"], args.max_pending, fault_every=args.fault_every,
                on_temperature=report_temperature if args.temperature == "given" else None)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t_start = time.monotonic()
    try:
        ports = daqs.start()
        port = free_port()
        service_url["base"] = f"http://127.0.0.1:{port}"
        cfg = write_config(tmp, files, ports, args, database_url, port)
        service_log = open(tmp / "service.log", "w")
        service = subprocess.Popen([sys.executable, "-m", "service.cli", "serve", "--config", str(cfg)],
                                   cwd=ROOT, env=env, stdout=service_log, stderr=subprocess.STDOUT)
        procs.append(service)
        if args.celery:
            for _ in range(args.workers):
                procs.append(subprocess.Popen([sys.executable, "-m", "service.cli", "worker", "--config", str(cfg),
                                               "--concurrency", "1"], cwd=ROOT, env=env, stdout=service_log,
                                              stderr=subprocess.STDOUT))
        import httpx

        deadline = time.monotonic() + 120
        while True:
            if service.poll() is not None:
                raise RuntimeError(f"the service exited ({service.returncode}); see {tmp / 'service.log'}")
            try:
                if httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=2).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError("the service did not answer /healthz within 120 s")
            time.sleep(0.2)
        service_up.set()
        log(f"service up (pid {service.pid}) on {url.split('@')[-1]}; {args.operations} operations, "
            f"{args.breakers} breakers, {'Celery' if args.celery else 'local pool'} x{args.workers}")
        engine = make_engine(url)
        total = sum(per)
        warm = {"rss": None, "workers": None}
        last_progress, last_count = time.monotonic(), -1
        while True:
            with engine.connect() as c:
                stored = int(c.scalar(select(func.count()).select_from(OperationRow)))
                state["pending"] = int(c.scalar(select(func.count()).select_from(FitRow)
                                                .where(FitRow.status.in_(("queued", "running")))))
            if warm["rss"] is None and stored >= max(1, total // 10):
                warm["rss"] = rss_mb(service.pid)
                warm["workers"] = sum(rss_mb(p) for p in _worker_pids(service, procs))
                log(f"warm-up done at {stored} operations: service RSS {warm['rss']:.1f} MB, "
                    f"workers {warm['workers']:.1f} MB")
            if stored != last_count:
                step = max(1, total // 20)
                crossed = stored // step != max(last_count, 0) // step
                last_progress, last_count = time.monotonic(), stored
                if crossed or stored == total:
                    el = time.monotonic() - t_start
                    log(f"{stored}/{total} stored, {state['pending']} fits pending, {el:.0f} s, "
                        f"{stored / max(el, 1e-9):.2f} op/s, RSS {rss_mb(service.pid):.1f} MB")
            if daqs.error:
                raise RuntimeError(f"DAQ emulators failed: {daqs.error!r}")
            if daqs.done.is_set() and state["pending"] == 0 and stored >= total:
                break
            if time.monotonic() - last_progress > 180:
                log("no new operation for 180 s: stopping (counted as lost)")
                break
            if service.poll() is not None:
                raise RuntimeError(f"the service died ({service.returncode}); see {tmp / 'service.log'}")
            time.sleep(0.1)
        # the last fits: wait for the queue to drain
        drain = time.monotonic() + 120
        while state["pending"] and time.monotonic() < drain:
            with engine.connect() as c:
                state["pending"] = int(c.scalar(select(func.count()).select_from(FitRow)
                                                .where(FitRow.status.in_(("queued", "running")))))
            time.sleep(0.2)
        elapsed = time.monotonic() - t_start
        rss_end = rss_mb(service.pid)
        workers_end = sum(rss_mb(p) for p in _worker_pids(service, procs))
        api_alarms = httpx.get(f"http://127.0.0.1:{port}/api/v1/alarms?state=all",
                               headers={"X-API-Key": ADMIN_KEY}, timeout=30).json()
        result = analyse(engine, url, tmp, scripts, daqs, per)
        result.update({
            "operations_requested": args.operations, "breakers": args.breakers,
            "database": "postgresql" if database_url else "sqlite",
            "executor": "celery" if args.celery else "local", "fit_workers": args.workers,
            "temperature": args.temperature,
            "rss_mb_after_warmup": round(warm["rss"] or 0.0, 1), "rss_mb_end": round(rss_end, 1),
            "rss_workers_mb_after_warmup": round(warm["workers"] or 0.0, 1),
            "rss_workers_mb_end": round(workers_end, 1),
            "alarms_visible_in_api": len(api_alarms),
            "faults_injected": dict(daqs.faults),
            "duration_s": round(elapsed, 1), "operations_per_s": round(result["operations_stored"] / elapsed, 3),
            "cores": os.cpu_count(), "finished_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "load_average_at_end": Path("/proc/loadavg").read_text().split()[:3],
        })
        result["rss_growth_rel"] = round(result["rss_mb_end"] / result["rss_mb_after_warmup"] - 1, 4) \
            if result["rss_mb_after_warmup"] else None
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(result, indent=2) + "\n")
        print(json.dumps(result, indent=2))
        return 0
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(30)
            except subprocess.TimeoutExpired:
                p.kill()
        daqs.stop()
        if engine is not None:
            engine.dispose()
        if not args.keep:
            scratch.close()
        if args.keep:
            log(f"kept {tmp}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)


def _worker_pids(service, procs) -> list[int]:
    """The fit workers: the service's pool children, or the Celery worker processes and theirs."""
    pids = children(service.pid)
    for p in procs[1:]:
        pids += [p.pid] + children(p.pid)
    return pids


def analyse(engine, url: str, tmp: Path, scripts, daqs: Daqs, per: list[int]) -> dict:
    from sqlalchemy import select

    from service.storage.models import AlarmRow, BreakerRow, FitRow, OperationRow, PrognosisRow

    with engine.connect() as c:
        breakers = {r.name: r.id for r in c.execute(select(BreakerRow.id, BreakerRow.name))}
        ops = c.execute(select(OperationRow.id, OperationRow.breaker_id, OperationRow.capture_path,
                               FitRow.status, FitRow.finished_at)
                        .join(FitRow, FitRow.operation_id == OperationRow.id)).all()
        alarms = c.execute(select(AlarmRow.breaker_id, AlarmRow.parameter, AlarmRow.level, AlarmRow.state,
                                  AlarmRow.evidence, AlarmRow.operation_id)).all()
        # the worker's prognosis, stored with each fit (issue 37): its last words per breaker
        prognoses = c.execute(select(PrognosisRow.breaker_id, PrognosisRow.parameter, PrognosisRow.result)).all()
    names = {v: k for k, v in breakers.items()}
    # each stored operation -> the scripted capture it came from, by stream position
    starts = [np.array([h[0] for h in handed]) for handed in daqs.handed]
    index_of = {s.breaker.name: i for i, s in enumerate(scripts)}
    seen: dict[tuple, int] = {}
    latency: list[tuple[float, float]] = []  # (handed at, fit visible after [s])
    decoys_stored = unmatched = 0
    capture_bytes = 0
    for op_id, breaker_id, path, status, finished in ops:
        i = index_of[names[breaker_id]]
        cfg = Path(path)
        for f in (cfg, cfg.with_suffix(".dat"), cfg.with_suffix(".hdr")):
            try:
                capture_bytes += f.stat().st_size
            except OSError:
                pass
        try:
            fsi = int(json.loads(cfg.with_suffix(".hdr").read_text())["first_sample_index"])
        except (OSError, ValueError, KeyError):
            unmatched += 1
            continue
        k = int(np.searchsorted(starts[i], fsi, side="right")) - 1
        if k < 0 or fsi >= starts[i][k] + daqs.handed[i][k][1]:
            unmatched += 1
            continue
        _, _, kind, handed_at = daqs.handed[i][k]
        if kind == "decoy":
            decoys_stored += 1
            continue
        seen[(i, k)] = seen.get((i, k), 0) + 1
        if finished is not None:
            if finished.tzinfo is None:
                finished = finished.replace(tzinfo=timezone.utc)
            latency.append((handed_at, finished.timestamp() - handed_at))
    scripted = sum(per)
    lost = sum(1 for i, handed in enumerate(daqs.handed) for k, h in enumerate(handed)
               if h[2] != "decoy" and (i, k) not in seen)
    duplicated = sum(n - 1 for n in seen.values() if n > 1)
    latency.sort()
    # the first operations wait for the fit workers' one-off start (imports, JIT compilation):
    # they are warm-up, not the service's steady state, and stay out of the first tenth
    warmup = max(8, len(latency) // 100)
    steady = latency[warmup:]
    tenth = max(1, len(steady) // 10)
    first = [d for _, d in steady[:tenth]]
    last = [d for _, d in steady[-tenth:]]
    n_ops = len(ops)
    fits_done = sum(1 for o in ops if o.status == "done")
    p95 = (lambda v: round(float(np.percentile(v, 95)), 3) if v else None)
    return {
        "operations_scripted": scripted, "operations_stored": n_ops - decoys_stored - unmatched,
        "lost": lost, "duplicated": duplicated, "decoys_scripted": sum(1 for h in daqs.handed for x in h
                                                                       if x[2] == "decoy"),
        "decoys_stored": decoys_stored, "operations_unmatched": unmatched,
        "fits_done": fits_done, "fits_failed": sum(1 for o in ops if o.status == "failed"),
        "db_bytes_per_operation": round(db_bytes(url, engine, tmp / "data") / max(n_ops, 1)),
        "capture_bytes_per_operation": round(capture_bytes / max(n_ops, 1)),
        "fit_visible_p95_s_first_10pct": p95(first), "fit_visible_p95_s_last_10pct": p95(last),
        "fit_visible_p95_ratio_last_first": round(p95(last) / p95(first), 3) if first and last else None,
        # issue 43: the p95 at the last 1,000 operations against the first 1,000 (after warm-up)
        "fit_visible_p95_s_first_1000": p95([d for _, d in steady[:1000]]),
        "fit_visible_p95_s_last_1000": p95([d for _, d in steady[-1000:]]),
        "fit_visible_p95_ratio_last_first_1000": round(p95([d for _, d in steady[-1000:]])
                                                       / p95([d for _, d in steady[:1000]]), 3) if steady else None,
        "fit_visible_warmup_operations_excluded": warmup,
        "fit_visible_p95_s_warmup": p95([d for _, d in latency[:warmup]]),
        **judge_alarms(scripts, alarms, names),
        "prognoses_last": {f"{names[b]} {par}": (res or {}).get("fleet") for b, par, res in prognoses},
    }


if __name__ == "__main__":
    sys.exit(main())
