"""One service, three emulated DAQs for three breakers: a streaming DAQ over pyserial
``socket://``, a capture-buffer DAQ on pymodbus's Modbus TCP server, and a replayed recording.
Every operation is stored under its own breaker; killing the Modbus emulator leaves the other two
capturing and shows that DAQ down in /healthz and /metrics."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from fastapi.testclient import TestClient

from conftest import make_settings
from fleet_helpers import ModbusDaq, breaker_files, capture_block, poll
from service.settings import load_settings

NAMES = ["bay-serial", "bay-modbus", "bay-replay"]


def _gated_stream(breaker, gate: threading.Event):
    """open, close; then (once ``gate`` is set) open, close again: the serial DAQ's stream."""
    from drivers.emulators.sources import synthetic_stream

    first = list(synthetic_stream(breaker, operations=("open", "close"), idle_s=0.3, seed=11))
    yield from first
    gate.wait(120)
    yield from synthetic_stream(breaker, operations=("open", "close"), idle_s=0.3, seed=12,
                                first_index=first[-1].end_index)


def _recording(breaker, path):
    """A COMTRADE recording: 2.5 s idle, an opening, 2.5 s idle, a closing, 2.5 s idle (replayed at
    half speed, the closing comes 10 s after the start, long after the Modbus DAQ is killed)."""
    from drivers.capture import Capture
    from drivers.emulators.sources import synthetic_stream
    from service.acquisition.comtrade_writer import write_comtrade

    blocks = list(synthetic_stream(breaker, operations=("open", "close"), idle_s=2.5, seed=21))
    cap = Capture(travel=np.concatenate([b.travel for b in blocks]), sample_rate=blocks[0].sample_rate,
                  vibration=np.concatenate([b.vibration for b in blocks]))
    return write_comtrade(cap, path, "recording")


def _ops(client, h, breaker_id):
    return client.get(f"/api/v1/breakers/{breaker_id}/operations?limit=100", headers=h).json()


def _daq(client, name):
    return next(d for d in client.get("/healthz").json()["daqs"] if d["name"] == name)


def test_three_daqs_three_breakers_and_one_killed(tmp_path):
    from drivers.emulators.serial_daq import SerialDaqEmulator
    from drivers.scaling import ChannelScaling
    from service.api.app import create_app
    from service.breaker_file import load_breaker

    files = breaker_files(tmp_path / "breakers", NAMES)
    bays = {n: load_breaker(f) for n, f in zip(NAMES, files)}
    gate = threading.Event()
    serial = SerialDaqEmulator(_gated_stream(bays["bay-serial"], gate), link="tcp", speed=1.0,
                               scaling=ChannelScaling.from_breaker(bays["bay-serial"])).start()
    modbus = ModbusDaq(bays["bay-modbus"])
    modbus.add(capture_block(bays["bay-modbus"], "open", 31, 0))
    modbus.add(capture_block(bays["bay-modbus"], "close", 32, 10_000_000))
    recording = _recording(bays["bay-replay"], tmp_path / "rec")
    acquisition = [
        {"driver": "serial", "breaker": "bay-serial", "serial": {"url": serial.url}},
        {"driver": "modbus", "breaker": "bay-modbus", "retry_min_s": 0.2, "retry_max_s": 1.0,
         "modbus": {"host": "127.0.0.1", "port": modbus.port, "poll_interval_s": 0.1, "timeout_s": 0.5}},
        {"driver": "replay", "breaker": "bay-replay", "replay": {"files": [str(recording)], "speed": 0.5}},
    ]
    url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    (tmp_path / "data").mkdir()
    from service.storage.db import upgrade

    upgrade(url)
    settings = make_settings(tmp_path, url, breakers=files, acquisition=acquisition,
                             fit_function="fleet_helpers:no_fit", daq_timeout_s=5.0)
    shown = []
    app = create_app(settings, on_key=shown.append)
    try:
        with TestClient(app) as client:
            h = {"X-API-Key": shown[0]}
            client.headers.update(h)  # /healthz gives its details to a key holder only
            ids = {b["name"]: b["id"] for b in client.get("/api/v1/breakers", headers=h).json()}
            assert set(ids) == set(NAMES)
            poll(lambda: len(_ops(client, h, ids["bay-modbus"])) == 2, 60, "the two Modbus captures")
            poll(lambda: len(_ops(client, h, ids["bay-serial"])) == 2, 60, "the first two serial operations")

            modbus.kill()
            killed_at = time.time()
            down = poll(lambda: (lambda d: d if d["down"] else None)(_daq(client, "bay-modbus")), 30,
                        "the Modbus DAQ shown down")
            assert down["up"] is False and down["state"] in ("running", "retrying")
            health = client.get("/healthz").json()
            assert health["status"] == "degraded" and health["daq_connected"] is False
            assert _daq(client, "bay-serial")["up"] is True
            assert _daq(client, "bay-replay")["down"] is False, _daq(client, "bay-replay")
            metrics = client.get("/metrics", headers=h).text
            assert 'hvcb_daq_down{breaker="bay-modbus",daq="bay-modbus",driver="modbus"} 1.0' in metrics
            assert 'hvcb_daq_up{breaker="bay-serial",daq="bay-serial",driver="serial"} 1.0' in metrics

            gate.set()  # the serial DAQ streams two more operations after the kill
            poll(lambda: len(_ops(client, h, ids["bay-serial"])) == 4, 60, "all four serial operations")
            poll(lambda: len(_ops(client, h, ids["bay-replay"])) == 2, 60, "both replayed operations")
            poll(lambda: _daq(client, "bay-replay")["state"] == "finished", 30, "the replay to finish")

            kinds = {n: sorted(o["kind"] for o in _ops(client, h, ids[n])) for n in NAMES}
            assert kinds == {"bay-serial": ["close", "close", "open", "open"], "bay-modbus": ["close", "open"],
                             "bay-replay": ["close", "open"]}
            ops = {n: _ops(client, h, ids[n]) for n in NAMES}
            assert all(o["source"] == "daq" and o["breaker_id"] == ids[n] for n in NAMES for o in ops[n])
            for n in ("bay-serial", "bay-replay"):  # both kept capturing after the Modbus DAQ died
                assert any(_epoch(o["received_at"]) > killed_at for o in ops[n]), n
            assert _daq(client, "bay-modbus")["down"] is True  # and it stays down, retried with backoff
            stored = next(d for d in client.get("/healthz").json()["daq"] if d["breaker"] == "bay-modbus")
            assert stored["connected"] is False  # the stored status (SCADA point) says so too
            assert len(_ops(client, h, ids["bay-modbus"])) == 2
    finally:
        gate.set()
        serial.close()
        modbus.kill()


def _epoch(text: str) -> float:
    from datetime import datetime

    return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()


def test_a_failing_driver_is_retried_with_backoff_and_never_stops_another(tmp_path, breaker):
    from service.acquisition.daq_runner import DaqGroup, DaqRunner
    from service.settings import AcquisitionSettings

    bad = AcquisitionSettings(driver="replay", breaker=breaker.name, name="broken", retry_min_s=0.05,
                              retry_max_s=0.2, replay={"files": [str(tmp_path / "missing.cfg")]})
    good = AcquisitionSettings(driver="replay", breaker=breaker.name, name="good",
                               replay={"files": [str(_recording(breaker, tmp_path / "rec"))], "speed": None})
    got = []
    group = DaqGroup([DaqRunner(bad, breaker, tmp_path / "a", on_capture=lambda *a: None),
                      DaqRunner(good, breaker, tmp_path / "b", on_capture=lambda p, d: got.append(d.operation))])
    group.start()
    try:
        poll(lambda: group.states()[0].restarts >= 3, 30, "three rebuilds of the broken driver")
        poll(lambda: group.states()[1].state == "finished", 60, "the good replay to finish")
        broken, fine = group.states()
        assert broken.down and broken.state in ("retrying", "starting", "running")
        assert "missing.cfg" in (broken.error or "")
        assert fine.captures == 2 and sorted(got) == ["close", "open"] and not fine.down
    finally:
        group.stop()
    assert [s.state for s in group.states()] == ["stopped", "finished"]


# -- settings -------------------------------------------------------------------------------------
def test_old_single_acquisition_table_is_read_with_a_deprecation_note(tmp_path, caplog):
    cfg = tmp_path / "old.toml"
    cfg.write_text('[acquisition]\ndriver = "modbus"\nbreaker = "reference-252kV"\n'
                   '[acquisition.modbus]\nhost = "10.0.0.5"\nport = 5020\n')
    with caplog.at_level("WARNING", logger="hvcb.settings"):
        s = load_settings(cfg)
    assert [(a.driver, a.breaker, a.modbus.port) for a in s.acquisition] == [("modbus", "reference-252kV", 5020)]
    assert "deprecated" in caplog.text and "[[acquisition]]" in caplog.text


def test_acquisition_list_and_its_errors(tmp_path):
    from pydantic import ValidationError

    cfg = tmp_path / "multi.toml"
    cfg.write_text('[[acquisition]]\ndriver = "modbus"\nbreaker = "a"\n'
                   '[[acquisition]]\ndriver = "serial"\nbreaker = "b"\nserial = {url = "socket://127.0.0.1:1"}\n'
                   '[[acquisition]]\ndriver = "none"\n')
    assert [a.breaker for a in load_settings(cfg).acquisition] == ["a", "b"]  # "none" entries are dropped
    for bad, words in ([{"driver": "modbus"}, {"driver": "modbus", "breaker": "b"}], "needs its `breaker`"), \
                      ([{"driver": "modbus", "breaker": "a"}, {"driver": "modbus", "breaker": "a"}], "same breaker"), \
                      ([{"driver": "modbus", "breaker": "a", "retry_min_s": 5, "retry_max_s": 1}], "retry_min_s"):
        with pytest.raises(ValidationError, match=words):
            load_settings(acquisition=bad)


def test_adding_and_removing_a_daq_is_a_restart_without_loss(tmp_path):
    """Run 1: one Modbus DAQ (bay-a). While the service is down bay-a records one more capture
    (held by the DAQ until acknowledged). Run 2 adds bay-b; run 3 removes bay-a."""
    from service.api.app import create_app
    from service.breaker_file import load_breaker
    from service.storage.db import upgrade

    files = breaker_files(tmp_path / "breakers", ["bay-a", "bay-b"])
    a_breaker, b_breaker = (load_breaker(f) for f in files)
    daq_a, daq_b = ModbusDaq(a_breaker), ModbusDaq(b_breaker)
    url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    (tmp_path / "data").mkdir()
    upgrade(url)

    def entry(name, daq):
        return {"driver": "modbus", "breaker": name, "modbus": {"port": daq.port, "poll_interval_s": 0.1}}

    keys = []

    def run(acquisition, expect):
        settings = make_settings(tmp_path, url, breakers=files, acquisition=acquisition,
                                 fit_function="fleet_helpers:no_fit")
        with TestClient(create_app(settings, on_key=keys.append)) as client:
            h = {"X-API-Key": keys[0]}
            client.headers.update(h)  # /healthz gives its details to a key holder only
            ids = {b["name"]: b["id"] for b in client.get("/api/v1/breakers", headers=h).json()}

            def counts():
                return {n: len(_ops(client, h, ids[n])) for n in ids}
            poll(lambda: counts() == expect, 60, f"operations {expect}")
            health = client.get("/healthz").json()
            assert [d["breaker"] for d in health["daqs"]] == [a["breaker"] for a in acquisition]
            poll(lambda: sorted(d["breaker"] for d in client.get("/healthz").json()["daq"])
                 == sorted(a["breaker"] for a in acquisition), 10, "the stored DAQ statuses")

    try:
        daq_a.add(capture_block(a_breaker, "open", 41, 0))
        daq_a.add(capture_block(a_breaker, "close", 42, 10_000_000))
        run([entry("bay-a", daq_a)], {"bay-a": 2, "bay-b": 0})
        daq_a.add(capture_block(a_breaker, "open", 43, 20_000_000))  # while the service is stopped
        daq_b.add(capture_block(b_breaker, "open", 51, 0))
        run([entry("bay-a", daq_a), entry("bay-b", daq_b)], {"bay-a": 3, "bay-b": 1})
        daq_b.add(capture_block(b_breaker, "close", 52, 10_000_000))
        run([entry("bay-b", daq_b)], {"bay-a": 3, "bay-b": 2})
        assert daq_a.acknowledged == 3 and daq_b.acknowledged == 2
    finally:
        daq_a.kill()
        daq_b.kill()
