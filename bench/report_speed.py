"""Condition report and CSV export on a long history: the report's time and size, the CSV's
peak memory while it streams.

Stores N operations (default 10,000; --quick 1,000) of the reference breaker in bulk, each with a
finished fit (tests/reports/history.py: DO leaking over the last 3 %, so an alarm is active and
the prognosis has a trend), then:

- the report: ``hvcb report`` as a command (wall and CPU time, the Python start, the imports and
  the settings included; as installed and with OpenBLAS on one thread),
  and in process the data gathering and the PDF rendering (wall and CPU, median of 3), the PDF's
  size and pages;
- the CSV of the operations: streamed chunk by chunk (each chunk dropped as a server drops it
  once sent), its peak Python memory (tracemalloc) for the first 2,000 operations and for all N:
  flat memory means the two peaks are about equal. (From two chunks on the peak is two chunks'
  worth, the one being sent and the one being read; a single chunk peaks lower.) For contrast,
  the peak when the whole file is built in memory first.

Writes bench/results/report_speed.json (report_speed_quick.json with --quick).

    python bench/report_speed.py [--operations 10000] [--quick] [--database-url postgresql+psycopg://...]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402

from service.breaker_file import load_breaker  # noqa: E402
from service.settings import load_settings  # noqa: E402
from service.storage import crud  # noqa: E402
from service.storage.db import make_engine, session_factory, upgrade  # noqa: E402
from tests.reports.history import T0, bulk_history  # noqa: E402

BREAKER_FILE = REPO / "config" / "breakers" / "reference-252kV.toml"


def stream_peak(Session, window, *, whole: bool = False) -> dict:
    """Peak traced memory [MB] while the operations CSV of ``window`` is produced: streamed
    (chunks dropped) or, with ``whole``, joined into one string first."""
    from service.reports.exports import operation_chunks

    tracemalloc.start()
    t = time.perf_counter()
    size = rows = chunks = 0
    if whole:
        text = "".join(operation_chunks(Session, breaker_id=1, window=window))
        size, rows, chunks = len(text.encode()), text.count("\r\n") - 1, 1
        del text
    else:
        for chunk in operation_chunks(Session, breaker_id=1, window=window):
            size += len(chunk.encode())
            rows += chunk.count("\r\n")
            chunks += 1
        rows -= 1
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"rows": rows, "bytes": size, "chunks": chunks, "peak_mb": round(peak / 1e6, 2),
            "seconds": round(time.perf_counter() - t, 2)}


def _via_service(settings, Session, env, out) -> dict:
    """The page's button against ``hvcb report`` asking that running service (issue 51 item 4):
    each the median of 3 after one warm-up, on the same database."""
    import urllib.request

    from service.api.app import create_app
    from tests.live_server import LiveServer

    with Session() as s, s.begin():
        _, key = crud.create_api_key(s, name="bench-reader", role="reader")
    app = create_app(settings, start_monitor=False)
    button, command = [], []
    with LiveServer(app, name="hvcb-report-bench") as server:
        def press():
            req = urllib.request.Request(f"{server.url}/api/v1/breakers/reference-252kV/report",
                                         headers={"X-API-Key": key})
            t = time.perf_counter()
            while True:  # the button's download: 202 while it is drawn, then the PDF
                with urllib.request.urlopen(req, timeout=600) as r:
                    if r.status == 200:
                        r.read()
                        return time.perf_counter() - t
                    req = urllib.request.Request(server.url + r.headers["Location"], headers={"X-API-Key": key})
                time.sleep(0.2)

        press()
        for _ in range(3):
            button.append(press())
        argv = [sys.executable, "-m", "service.cli", "report", "reference-252kV", "-o", str(out),
                "--url", server.url, "--key", key]
        for i in range(4):
            t = time.perf_counter()
            run = subprocess.run(argv, cwd=REPO, env=env, capture_output=True, text=True)
            if run.returncode != 0:
                raise SystemExit(run.stderr)
            if i:
                command.append(time.perf_counter() - t)
    b, c = statistics.median(button), statistics.median(command)
    return {"button_wall_s": round(b, 2), "command_wall_s": round(c, 2), "command_over_button": round(c / b, 2)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--operations", type=int, default=10_000)
    ap.add_argument("--quick", action="store_true", help="1,000 operations")
    ap.add_argument("--database-url", default=None, help="an empty, migrated-or-not database (default: SQLite)")
    args = ap.parse_args(argv)
    n = 1000 if args.quick else args.operations

    from drivers.synthetic import synthesize_capture
    from service.acquisition.comtrade_writer import write_comtrade
    from service.reports.content import gather
    from service.reports.pdf import render
    from service.reports.window import Window

    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data"
        data.mkdir()
        url = args.database_url or f"sqlite:///{data / 'hvcb.sqlite3'}"
        upgrade(url)
        settings = load_settings(data_dir=data, database_url=url, broker_url="", executor="inline",
                                 bootstrap_admin_key=None)
        Session = session_factory(make_engine(url))
        breaker = load_breaker(BREAKER_FILE)
        with Session() as s, s.begin():
            crud.register_breaker_file(s, path=BREAKER_FILE, tag="Q1")
        cap, _ = synthesize_capture(breaker, "open", dict(breaker.design_parameters()), rng=np.random.default_rng(1))
        cfg = write_comtrade(cap, data / "captures", "latest")
        t = time.perf_counter()
        bulk_history(Session, settings.drift_settings, breaker, capture_path=str(cfg), n=n)
        history_s = time.perf_counter() - t

        out = data / "report.pdf"
        env = {**os.environ, "DATABASE_URL": url, "HVCB_DATA_DIR": str(data), "PYTHONPATH": str(REPO)}
        command = {}
        # as installed, and with OpenBLAS on one thread: loading the settings designs the CUSUM
        # thresholds (numpy.linalg.solve), which OpenBLAS's threads slow down on a busy machine
        for label, extra in (("default", {}), ("openblas_1_thread", {"OPENBLAS_NUM_THREADS": "1"})):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            run = subprocess.run([sys.executable, "-m", "service.cli", "report", "reference-252kV", "-o", str(out)],
                                 cwd=REPO, env={**env, **extra}, capture_output=True, text=True)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            if run.returncode != 0:
                print(run.stderr, file=sys.stderr)
                return 1
            command[label] = {"wall_s": round(time.perf_counter() - t, 2),
                              "cpu_s": round(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, 2)}
        via_service = _via_service(settings, Session, env, out)
        pages = subprocess.run(["pdfinfo", str(out)], capture_output=True, text=True).stdout
        pages = next((int(line.split()[-1]) for line in pages.splitlines() if line.startswith("Pages:")), None)

        gathers, renders, cpus = [], [], []
        for _ in range(3):
            c0, t0 = time.process_time(), time.perf_counter()
            with Session() as s:
                content = gather(s, breaker=crud.get_breaker(s, breaker_id=1), settings=settings.drift_settings)
            t1 = time.perf_counter()
            pdf = render(content)
            gathers.append(t1 - t0)
            renders.append(time.perf_counter() - t1)
            cpus.append(time.process_time() - c0)

        first_k = Window(None, T0 + (min(n, 2000) - 1) * (content.counts["last"] - T0) / max(n - 1, 1))
        streamed_2k = stream_peak(Session, first_k)
        streamed = stream_peak(Session, Window())
        whole = stream_peak(Session, Window(), whole=True)

    result = {
        "operations": n, "database": url.split(":")[0], "history_insert_s": round(history_s, 2),
        "report": {"command": command, "via_service": via_service, "gather_s": round(statistics.median(gathers), 2),
                   "render_s": round(statistics.median(renders), 2), "cpu_s": round(statistics.median(cpus), 2),
                   "pdf_bytes": len(pdf), "pages": pages},
        "csv_operations": {"streamed_first_2000": streamed_2k, "streamed_all": streamed,
                           "built_whole_for_contrast": whole},
        "load_average": os.getloadavg()[0],
        "note": "wall times on the shared 2-core machine (other sessions running); cpu_s is this process's",
    }
    print(json.dumps(result, indent=2))
    name = "report_speed_quick.json" if args.quick else "report_speed.json"
    (REPO / "bench" / "results" / name).write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
