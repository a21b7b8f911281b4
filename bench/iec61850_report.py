"""IEC 61850 server: how fast a stored alarm reaches a subscribed client, and a full point read.

Each run starts the service (SQLite, inline executor) with the IEC 61850 server on a free port,
stores 12 healthy opening fits (baseline 10), subscribes libiec61850's client to the alarm
report, then stores fits with DO falling 2 %/operation until the drift detector raises the DO
alarm. Latency = from the commit of that fit to the report carrying SOPM1.DOWrn = true (wall
clock; the server polls the database every 0.5 s). Also times one read of all 110 points of
the logical device. Prints the figures; writes bench/results/iec61850_report.json.

    python bench/iec61850_report.py [--runs 8]
"""

from __future__ import annotations

import argparse
import json
import socket
import statistics
import sys
import tempfile
import threading
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import pyiec61850.pyiec61850 as L  # noqa: E402
from pyiec61850.mms import MMSClient  # noqa: E402
from pyiec61850.mms.exceptions import MMSError  # noqa: E402
from pyiec61850.mms.utils import mms_value_to_python  # noqa: E402

from service.alarms.settings import DriftSettings  # noqa: E402
from service.iec61850 import points as pm  # noqa: E402
from service.jobs.fit import update_drift  # noqa: E402
from service.settings import load_settings  # noqa: E402
from service.storage import crud  # noqa: E402
from service.storage.db import upgrade  # noqa: E402

ALARMS = {"baseline_n": 10, "watched": {"DO": "falling", "BO": "both"}}


class Reports(L.RCBHandler):
    def __init__(self, members):
        super().__init__()
        self.members, self.event, self.when = members, threading.Event(), None

    def trigger(self):
        values = L.ClientReport_getDataSetValues(self._client_report)
        i = self.members.index("SOPM1.DOWrn")
        if mms_value_to_python(L.MmsValue_getElement(values, i))[0] is True and self.when is None:
            self.when = time.monotonic()
            self.event.set()


def store_fit(Session, i, t0, do, settings):
    with Session() as s, s.begin():
        op, _ = crud.create_operation(s, capture_key=f"k{i}", breaker_id=1, kind="open",
                                      occurred_at=t0 + timedelta(seconds=i), source="replay",
                                      capture_path="/nonexistent.csv", capture_sha256="0" * 64, flags=[],
                                      sample_rate=1.0, n_samples=1)
        crud.claim_fit(s, operation_id=op.id, worker="bench")
        crud.store_fit_result(s, operation_id=op.id, curve=None, result={
            "parameters": {"AO": 3424.0, "BO": 4806.0, "DO": do, "EO": 3950.0},
            "ci95": {"DO": [do - 0.3, do + 0.3], "BO": [4790.0, 4822.0]}, "identifiable": True,
            "characteristics": {"operating_time_s": 0.021}})
        return update_drift(s, breaker_id=1, settings=settings)


def connect(port):
    for _ in range(5):  # libiec61850's client now and then fails a fresh association's first request
        client = MMSClient()
        client.connect("127.0.0.1", port)
        try:
            client.get_logical_devices()
            return client
        except MMSError:
            client.disconnect()
    raise RuntimeError("no MMS association")


def one_run(run: int, tmp: Path) -> tuple[float, float]:
    from fastapi.testclient import TestClient

    from service.api.app import create_app

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    (tmp / "data").mkdir(parents=True)
    url = f"sqlite:///{tmp / 'data' / 'hvcb.sqlite3'}"
    upgrade(url)
    settings = load_settings(data_dir=tmp / "data", database_url=url, broker_url="", executor="inline",
                             bootstrap_admin_key=None, iec61850_port=port, alarms=ALARMS)
    drift = DriftSettings.from_mapping(ALARMS)
    app = create_app(settings, on_key=lambda key: None)
    with TestClient(app):
        Session, rng = app.state.Session, np.random.default_rng(run)
        t0 = datetime.now(timezone.utc) - timedelta(hours=1)
        for i in range(12):
            store_fit(Session, i, t0, 39.5 * (1 + rng.normal(0, 0.003)), drift)
        client = connect(port)
        (ld,) = app.state.iec61850.logical_devices
        started = time.perf_counter()
        for p in pm.points(ld):
            client.read_value(p.reference, p.fc)
        read_s = time.perf_counter() - started
        reports, conn = Reports(list(ld.dataset)), client._connection
        ref = f"{ld.name}/LLN0.RP.{pm.RCB}"
        rcb = L.ClientReportControlBlock_create(ref)
        L.IedConnection_getRCBValues(conn, ref, rcb)
        sub = L.RCBSubscriber()
        sub.setIedConnection(conn)
        sub.setRcbReference(ref)
        sub.setRcbRptId(L.ClientReportControlBlock_getRptId(rcb))
        sub.setEventHandler(reports)
        reports.__disown__()
        sub.subscribe()
        L.ClientReportControlBlock_setRptEna(rcb, True)
        L.IedConnection_setRCBValues(conn, rcb, L.RCB_ELEMENT_RPT_ENA, True)
        committed = None
        for i in range(12, 40):
            events = store_fit(Session, i, t0, 39.5 * 0.98 ** (i - 11), drift)
            if any(e.kind == "raised" for e in events):
                committed = time.monotonic()
                break
        if committed is None or not reports.event.wait(30):
            raise RuntimeError("no alarm report")
        latency = reports.when - committed
        L.ClientReportControlBlock_destroy(rcb)
        del sub
        client.disconnect()
    return latency, read_s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=8)
    args = ap.parse_args()
    lat, reads = [], []
    with tempfile.TemporaryDirectory() as d:
        for run in range(args.runs):
            latency, read_s = one_run(run, Path(d) / f"run{run}")
            lat.append(latency)
            reads.append(read_s)
    out = {"runs": args.runs, "poll_s": 0.5, "points": 110,
           "report_latency_s": {"median": statistics.median(lat), "max": max(lat), "min": min(lat),
                                "all": [round(x, 4) for x in lat]},
           "read_all_points_s": {"median": statistics.median(reads), "max": max(reads)}}
    print(f"alarm commit -> report: median {out['report_latency_s']['median']:.3f} s, "
          f"min {min(lat):.3f} s, max {max(lat):.3f} s over {args.runs} runs (poll 0.5 s)")
    print(f"read of all 110 points: median {out['read_all_points_s']['median'] * 1000:.0f} ms")
    path = REPO / "bench" / "results" / "iec61850_report.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path.relative_to(REPO)}")


if __name__ == "__main__":
    main()
