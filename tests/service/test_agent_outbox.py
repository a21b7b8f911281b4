"""The edge agent's outbox: durable FIFO bounded by size (oldest kept, alarm when full), crash
recovery, and the forwarder's answers to a real central server (sent, duplicate, rejected)."""

from __future__ import annotations

import logging
from datetime import datetime, timedelta, timezone

import pytest

from conftest import BREAKER_FILE, make_settings, synth
from fleet_helpers import Central, free_port
from service.agent.outbox import Outbox
from service.storage import crud
from service.storage.db import upgrade

T0 = datetime(2026, 1, 1, tzinfo=timezone.utc)


def _capture(breaker, capture_dir, i, kind="open"):
    from service.acquisition.comtrade_writer import write_comtrade

    return write_comtrade(synth(breaker, kind, seed=i), capture_dir / breaker.name, f"op-{i:04d}-{kind}")


def _size(cfg):
    return sum(p.stat().st_size for p in cfg.parent.glob(cfg.stem + ".*"))


def test_outbox_keeps_order_and_refuses_new_captures_when_full(tmp_path, breaker, caplog):
    caps = tmp_path / "captures"
    sizes = tmp_path / "sizes"
    one = _size(_capture(breaker, sizes, 0))
    ob = Outbox(tmp_path / "outbox", caps, max_bytes=2 * one + one // 2)
    files = [_capture(breaker, caps, i) for i in range(3)]
    for i, f in enumerate(files[:2]):
        ob.put(f, breaker=breaker.name, operation="open", captured_at=T0 + timedelta(seconds=i))
    with caplog.at_level(logging.ERROR, logger="hvcb.agent.outbox"):
        assert ob.put(files[2], breaker=breaker.name, operation="open", captured_at=T0 + timedelta(seconds=2)) is None
    assert "ALARM" in caplog.text and "outbox is full" in caplog.text
    assert ob.full and ob.dropped == 1 and len(ob) == 2 and not files[2].exists()  # the oldest are kept
    first = ob.oldest()
    assert first.cfg == str(files[0].resolve()) and first.seq == 1
    assert ob.oldest_age_s(T0 + timedelta(seconds=10)) == pytest.approx(10.0)
    ob.sent(first)
    assert not files[0].exists() and not files[0].with_suffix(".dat").exists()
    assert not ob.full and len(ob) == 1 and ob.oldest().cfg == str(files[1].resolve())


def test_outbox_recovers_after_a_crash(tmp_path, breaker):
    caps = tmp_path / "captures"
    ob = Outbox(tmp_path / "outbox", caps, max_bytes=10 ** 9)
    files = [_capture(breaker, caps, i, kind) for i, kind in enumerate(["open", "close", "open"])]
    e0 = ob.put(files[0], breaker=breaker.name, operation="open", captured_at=T0)
    ob.put(files[1], breaker=breaker.name, operation="close", captured_at=T0 + timedelta(seconds=1))
    # crash after the first was sent (files deleted, entry not yet), before the third was journalled
    for p in files[0].parent.glob(files[0].stem + ".*"):
        p.unlink()
    again = Outbox(tmp_path / "outbox", caps, max_bytes=10 ** 9)
    pending = []
    while (e := again.oldest()) is not None:
        pending.append(e)
        again.sent(e)
    assert [(e.cfg, e.operation, e.breaker) for e in pending] == [
        (str(files[1].resolve()), "close", breaker.name), (str(files[2].resolve()), "open", breaker.name)]
    assert pending[0].key != e0.key and pending[0].seq > e0.seq


def test_forwarder_sends_dedupes_and_sets_aside_what_the_server_refuses(tmp_path, breaker):
    from service.agent.forwarder import Forwarder
    from service.agent.settings import CentralSettings

    url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    (tmp_path / "data").mkdir()
    upgrade(url)
    central = Central(make_settings(tmp_path, url, breakers=[BREAKER_FILE], port=free_port(),
                                    fit_function="fleet_helpers:no_fit"))
    central.start()
    try:
        with central.app.state.Session() as s, s.begin():
            key = crud.create_api_key(s, name="edge", role="agent")[1]
        caps = tmp_path / "captures"
        ob = Outbox(tmp_path / "outbox", caps, max_bytes=10 ** 9)
        good = _capture(breaker, caps, 1)
        bad = _capture(breaker, caps, 2)
        bad.write_text("not a COMTRADE configuration\n")
        bad_entry = ob.put(bad, breaker=breaker.name, operation="open", captured_at=T0)
        good_entry = ob.put(good, breaker=breaker.name, operation="open", captured_at=T0)
        fw = Forwarder(ob, CentralSettings(url=central.url, api_key=key, breaker_ids={breaker.name: 1}))
        try:
            assert fw.send(bad_entry) == "rejected"
            assert (tmp_path / "outbox" / "rejected" / bad.name).exists() and ob.rejected == 1
            assert fw.send(good_entry) == "sent" and len(ob) == 0 and fw.duplicates == 0
            # the same capture sent again (an acknowledgement lost on the way): stored once
            again = _capture(breaker, caps, 1)
            assert fw.send(ob.put(again, breaker=breaker.name, operation="open", captured_at=T0)) == "sent"
            assert fw.duplicates == 1
            wrong = CentralSettings(url=central.url, api_key="hvcb_" + "x" * 40, breaker_ids={breaker.name: 1})
            fw2 = Forwarder(ob, wrong)
            third = ob.put(_capture(breaker, caps, 3), breaker=breaker.name, operation="open", captured_at=T0)
            assert fw2.send(third) == "retry" and "401" in fw2.last_error and len(ob) == 1  # kept
            fw2.client.close()
        finally:
            fw.client.close()
        with central.app.state.Session() as s:
            assert crud.count_operations(s) == 1
    finally:
        central.stop()


def test_agent_command_refuses_bad_settings_in_one_line(tmp_path, capsys):
    from service.cli import main

    assert main(["agent", "--config", str(tmp_path / "missing.toml")]) == 2
    assert "agent settings file not found" in capsys.readouterr().err
    cfg = tmp_path / "edge.toml"
    cfg.write_text(f'breakers = ["{BREAKER_FILE}"]\n[[acquisition]]\ndriver = "modbus"\n'
                   '[central]\nurl = "https://central.example"\napi_key = ""\nbreaker_ids = {}\n')
    assert main(["agent", "--config", str(cfg)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "hvcb key NAME --role agent" in err and "Traceback" not in err
