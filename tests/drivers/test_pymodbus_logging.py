"""pymodbus's own ERROR lines (with a hex dump of the last frames) stay out of the output once a
driver builds its client or an emulator its server; an explicit configuration is respected."""

import asyncio
import logging

import pytest
from pymodbus.logging import Log

from drivers.emulators.modbus_daq import ModbusDaqEmulator
from drivers.modbus import ModbusSettings, make_client
from drivers.pymodbus_logging import PYMODBUS_LOGGER


@pytest.fixture
def unconfigured_pymodbus():
    logger = logging.getLogger(PYMODBUS_LOGGER)
    saved = logger.level
    logger.setLevel(logging.NOTSET)
    yield logger
    logger.setLevel(saved)


def build_client():
    async def build():
        make_client(ModbusSettings(host="127.0.0.1", port=1)).close()

    asyncio.run(build())


def cancel_send_lines(caplog, capfd):
    """What pymodbus's 'not connected' error leaves in the log records and on the terminal."""
    caplog.clear()
    Log.transport_dump(Log.SEND_DATA, b"\x00\x01\x00\x00\x00\x06\x01\x03\x00\x00\x00\x10", None)
    Log.error("Cancel send, because not connected!")
    err = capfd.readouterr().err
    return [r.getMessage() for r in caplog.records if r.name.startswith("pymodbus")], err


def test_an_unconfigured_pymodbus_logs_its_errors(unconfigured_pymodbus, caplog, capfd):
    """The noise this module removes is real: pymodbus logs the error with the raw frames."""
    records, _ = cancel_send_lines(caplog, capfd)
    assert records and "Cancel send" in records[0] and "0x3" in records[0]


def test_building_a_client_silences_pymodbus_errors(unconfigured_pymodbus, caplog, capfd):
    build_client()
    records, err = cancel_send_lines(caplog, capfd)
    assert records == [] and "Cancel send" not in err


def test_starting_an_emulator_silences_pymodbus_errors(unconfigured_pymodbus, caplog, capfd):
    async def serve():
        async with ModbusDaqEmulator(iter(()), port=0):
            pass

    asyncio.run(serve())
    records, err = cancel_send_lines(caplog, capfd)
    assert records == [] and "Cancel send" not in err


def test_an_explicit_pymodbus_level_is_kept(unconfigured_pymodbus):
    unconfigured_pymodbus.setLevel(logging.DEBUG)
    build_client()
    assert unconfigured_pymodbus.level == logging.DEBUG
