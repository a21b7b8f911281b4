"""``hvcb emulate``: the parser, and a Modbus emulator run that a driver drains."""

import argparse
import asyncio
import json
import threading

import pytest

from drivers import commands
from drivers.modbus import ModbusCaptureDriver, ModbusSettings


def parser():
    p = argparse.ArgumentParser(prog="hvcb")
    commands.register(p.add_subparsers(dest="command", required=True))
    return p


def test_serial_options_parse():
    args = parser().parse_args(["emulate", "serial", "--pty", "--speed", "0", "--drop-every", "50"])
    assert args.pty and args.speed == 0 and args.drop_every == 50 and args.func is commands.run_serial


def test_missing_breaker_file_is_a_clear_error():
    args = parser().parse_args(["emulate", "modbus", "--breaker", "/nonexistent.toml"])
    with pytest.raises(ValueError, match="breaker file not found"):
        args.func(args)


def test_modbus_emulator_serves_captures_to_a_driver(capsys, monkeypatch):
    ports = []
    from drivers.emulators import modbus_daq

    class Recording(modbus_daq.ModbusDaqEmulator):
        async def start(self):
            url = await super().start()
            ports.append(self.port)
            return url

    monkeypatch.setattr(modbus_daq, "ModbusDaqEmulator", Recording)
    args = parser().parse_args(["emulate", "modbus", "--port", "0", "--captures", "1", "--linger", "0.1"])
    got = []

    def drain():
        async def main():
            while not ports:
                await asyncio.sleep(0.01)
            drv = ModbusCaptureDriver(ModbusSettings(port=ports[0], poll_interval_s=0.01, timeout_s=0.5))
            async for block in drv:
                got.append(block)
                await drv.release()  # the capture is handled: the DAQ may free it
                break
            await drv.aclose()
        asyncio.run(main())

    t = threading.Thread(target=drain)
    t.start()
    assert args.func(args) == 0
    t.join()
    out = capsys.readouterr().out
    assert "--port" in out and len(got) == 1 and "capture" in got[0].flags
    assert json.loads(out.strip().splitlines()[-1])["captures_acknowledged"] == 1


def test_emulator_source_plays_the_scripted_stream(breaker):
    from drivers.emulators.sources import emulator_source

    blocks = []
    for block in emulator_source(breaker, seed=1, duration_s=0.05, fs=128000.0):
        blocks.append(block)
    assert sum(b.travel.size for b in blocks) == 6400
    assert [b.first_sample_index for b in blocks] == [0, 4096]
    with pytest.raises(ValueError, match="script"):
        emulator_source(breaker, seed=1, duration_s=1, fs=128000.0, script="nope")
