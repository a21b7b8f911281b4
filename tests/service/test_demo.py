"""The demo's real chain: Modbus TCP DAQ emulator on loopback → Modbus driver → trigger →
durable COMTRADE → ingest → fit jobs (local process pool) → REST, with a compressed history:
a healthy baseline, then a buffer oil leak. Fits must show over HTTP and the DO alarm must rise."""

from __future__ import annotations

import time

import pytest

from conftest import make_settings
from service.api.demo import DemoDaq, DemoScript

SCRIPT = DemoScript(healthy_ops=22, leak_per_op=0.03, total_ops=40, close_every=8, interval_s=0.15, seed=3)
SCRIPT_CAPTURES = 45  # 40 openings and a closing after every 8th


@pytest.fixture
def demo(tmp_path, breaker):
    from fastapi.testclient import TestClient

    from service.api.app import create_app
    from service.storage.db import upgrade

    daq = DemoDaq(breaker, SCRIPT)
    port = daq.start()
    try:
        url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
        (tmp_path / "data").mkdir()
        upgrade(url)
        settings = make_settings(tmp_path, url, executor="local", acquisition={
            "driver": "modbus", "modbus": {"host": "127.0.0.1", "port": port, "poll_interval_s": 0.05}})
        shown = []
        app = create_app(settings, on_key=shown.append)
        with TestClient(app) as client:
            yield client, {"X-API-Key": shown[0]}, daq
    finally:
        daq.stop()


def _poll(fn, timeout, what):
    deadline = time.monotonic() + timeout
    last = None
    while time.monotonic() < deadline:
        last = fn()
        if last:
            return last
        time.sleep(0.25)
    raise AssertionError(f"{what} not seen within {timeout} s (last: {last!r})")


def test_demo_chain_shows_fits_then_a_do_alarm_for_the_oil_leak(demo, tmp_path):
    client, h, daq = demo
    health = client.get("/healthz", headers=h).json()
    assert health["daq_driver"] == "modbus"
    _poll(lambda: client.get("/healthz", headers=h).json()["daq_connected"], 30, "DAQ connected")

    def do_trend():
        r = client.get("/api/v1/breakers/1/parameters", params={"name": "DO"}, headers=h)
        assert r.status_code == 200
        return r.json()["points"]

    first = _poll(do_trend, 60, "a DO fit")
    assert 30 < first[0]["value"] < 50  # the reference breaker's DO ≈ 39.5 s⁻¹

    def do_alarm():
        r = client.get("/api/v1/alarms", params={"state": "active"}, headers=h)
        return [a for a in r.json() if a["parameter"] == "DO"]

    (alarm,) = _poll(do_alarm, 150, "the DO alarm")
    points = do_trend()
    assert len(points) >= 21  # the baseline was complete before the alarm
    baseline = sum(p["value"] for p in points[:20]) / 20
    assert points[-1]["value"] < 0.97 * baseline  # DO fell: the leak is in the fits
    assert alarm["state"] == "raised" and alarm["level"] in ("warning", "alarm")

    _poll(lambda: daq.done.is_set(), 60, "the history played out")
    metrics = _poll(lambda: (lambda t: t if 'hvcb_daq_captures_total{breaker="reference-252kV"} 45.0' in t else None)(
        client.get("/metrics", headers=h).text), 30, "all 45 captures in the metrics")
    assert 'hvcb_frames_dropped_total{breaker="reference-252kV"} 0.0' in metrics
    assert 'hvcb_crc_errors_total{breaker="reference-252kV"} 0.0' in metrics
    health = client.get("/healthz", headers=h).json()
    (entry,) = health["daq"]
    assert entry["connected"] and entry["captures"] == 45 and entry["crc_errors"] == 0

    # The history is over: no capture can arrive between the API's list and the rows behind it.
    def all_operations():
        ops = client.get("/api/v1/breakers/1/operations", params={"limit": 1000}, headers=h).json()
        return ops if len(ops) >= SCRIPT_CAPTURES else None

    ops = _poll(all_operations, 30, f"all {SCRIPT_CAPTURES} operations")
    assert len(ops) == SCRIPT_CAPTURES and all(o["source"] == "daq" for o in ops)
    assert {"open", "close"} <= {o["kind"] for o in ops}
    # the operations point at the durable COMTRADE files the acquisition pipeline wrote
    from service.storage.models import OperationRow

    with client.app.state.Session() as s:
        paths = [r.capture_path for r in s.query(OperationRow)]
    daq_dir = (tmp_path / "data" / "captures" / "daq").resolve()
    assert len(paths) == len(ops) and all(p.startswith(str(daq_dir)) and p.endswith(".cfg") for p in paths)
