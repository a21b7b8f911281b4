"""Modbus end to end against pymodbus's own server: TCP and RTU framing over socket://."""

import asyncio

import numpy as np
import pytest

from drivers.emulators.modbus_daq import ModbusDaqEmulator
from drivers.emulators.sources import NOMINAL
from drivers.interface import Driver, SampleBlock
from drivers.modbus import CAPTURE_FLAG, ModbusCaptureDriver, ModbusSettings
from drivers.scaling import ChannelScaling
from drivers.synthetic import synthesize_capture

SCALING = ChannelScaling()


@pytest.fixture(scope="module")
def captures(breaker):
    """Two real opening captures (about 10 k samples each) and a short one."""
    rng = np.random.default_rng(11)
    out = []
    for k in range(2):
        cap, _ = synthesize_capture(breaker, "open", NOMINAL["open"], rng=rng)
        out.append(SampleBlock(k * 1_280_000, cap.travel, cap.vibration, cap.sample_rate))
    out.append(SampleBlock(2**40, out[0].travel[:333], out[0].vibration[:333], 128000.0))
    return out


def settings_for(em, **kw):
    base = dict(transport=em.transport, host=em.host, port=em.port, url=em.url, timeout_s=1.0,
                poll_interval_s=0.01)
    base.update(kw)
    return ModbusSettings(**base)


async def download(em, n, **kw):
    drv = ModbusCaptureDriver(settings_for(em, **kw), SCALING)
    got = []
    try:
        async def consume():
            async for block in drv:
                got.append(block)
                await drv.release()
                if len(got) == n:
                    return
        await asyncio.wait_for(consume(), timeout=30)
    finally:
        await drv.aclose()
    return drv, got


def assert_exact(got, served):
    assert len(got) == len(served)
    for block, cap in zip(got, served):
        assert block.flags == frozenset({CAPTURE_FLAG})
        assert block.first_sample_index == cap.first_sample_index
        assert block.sample_rate == cap.sample_rate_hz
        assert np.array_equal(SCALING.travel_to_code(block.travel), cap.codes[:, 0])
        assert np.array_equal(SCALING.vibration_to_code(block.vibration), cap.codes[:, 1])


@pytest.mark.parametrize("transport", ["tcp", "rtu"])
def test_captures_download_exactly(captures, transport):
    async def main():
        async with ModbusDaqEmulator(captures, transport=transport) as em:
            drv, got = await download(em, len(captures))
            return drv, em, got

    drv, em, got = asyncio.run(main())
    assert isinstance(drv, Driver)
    assert_exact(got, em.served)
    assert drv.stats.captures == em.stats.captures_acknowledged == 3
    assert (drv.stats.retries, drv.stats.abandoned, em.stats.bad_acks) == (0, 0, 0)
    # Reads never exceed 125 registers: a 10 k-sample capture needs at least 160 payload reads.
    assert em.stats.payload_reads >= 2 * int(np.ceil(2 * captures[0].travel.size / 125))


@pytest.mark.parametrize("transport", ["tcp", "rtu"])
def test_timeout_mid_download_is_retried_and_the_capture_is_still_exact(captures, transport):
    async def main():
        async with ModbusDaqEmulator(captures[:1], transport=transport) as em:
            em.inject_delay(0.6, at_read=40)  # longer than the 0.3 s timeout
            drv, got = await download(em, 1, timeout_s=0.3, settle_s=0.7)
            return drv, em, got

    drv, em, got = asyncio.run(main())
    assert em.stats.delays_injected == 1
    assert drv.stats.retries >= 1 and drv.stats.abandoned == 0
    assert_exact(got, em.served)


@pytest.mark.parametrize("transport", ["tcp", "rtu"])
def test_exhausted_retries_abandon_the_capture_and_fetch_it_whole_again(captures, transport):
    async def main():
        async with ModbusDaqEmulator(captures[2:], transport=transport) as em:
            em.inject_exception(at_read=2)
            drv, got = await download(em, 1, block_retries=0)
            return drv, em, got

    drv, em, got = asyncio.run(main())
    assert em.stats.exceptions_injected == 1
    assert drv.stats.abandoned >= 1 and drv.stats.captures == 1
    assert em.stats.captures_acknowledged == 1  # acknowledged once, after the good download
    assert_exact(got, em.served)


def test_an_idle_daq_yields_nothing_and_polling_stops_on_close():
    async def main():
        async with ModbusDaqEmulator([]) as em:
            drv = ModbusCaptureDriver(settings_for(em))
            task = asyncio.ensure_future(drv.__anext__())
            await asyncio.sleep(0.2)
            assert not task.done() and drv.stats.connected
            await drv.aclose()
            with pytest.raises(StopAsyncIteration):
                await asyncio.wait_for(task, timeout=5)
            return em

    em = asyncio.run(main())
    assert em.stats.reads > 1 and em.stats.payload_reads == 0


def test_settings_refuse_nonsense():
    with pytest.raises(ValueError, match="RTU needs"):
        ModbusSettings(transport="rtu")
    with pytest.raises(ValueError, match="max_block_registers"):
        ModbusSettings(max_block_registers=200)
    with pytest.raises(ValueError, match="'tcp' or 'rtu'"):
        ModbusSettings(transport="udp")
