"""Serial end to end: emulator → pty or socket:// → SerialStreamDriver, against the truth."""

import asyncio
import socket

import numpy as np
import pytest

from drivers.emulators.serial_daq import FaultPlan, SerialDaqEmulator
from drivers.errors import DriverError
from drivers.interface import Driver
from drivers.scaling import ChannelScaling
from drivers.serial_stream import GAP_FLAG, SerialSettings, SerialStreamDriver

SCALING = ChannelScaling()


def truth_arrays(blocks):
    travel = np.clip(np.concatenate([b.travel for b in blocks]), *SCALING.travel_limits)
    vib = np.clip(np.concatenate([b.vibration for b in blocks]), *SCALING.vibration_limits)
    return blocks[0].first_sample_index, travel, vib


async def run_chain(blocks, link, faults=None, *, speed=None):
    """Stream ``blocks`` through the emulator into the driver until the last sample arrives."""
    end = blocks[-1].end_index
    em = SerialDaqEmulator(blocks, link=link, speed=speed, faults=faults)
    drv = SerialStreamDriver(SerialSettings(em.url, reconnect_min_s=0.02, reconnect_max_s=0.1))
    got = []
    try:
        aiter = drv.__aiter__()
        while not drv.stats.connected:  # a pty drops what was written before the port opened
            await asyncio.sleep(0.005)
        em.start()

        async def consume():
            async for block in aiter:
                got.append(block)
                if block.end_index >= end:
                    return

        await asyncio.wait_for(consume(), timeout=20)
    finally:
        await drv.aclose()
        em.close()
    return drv, em, got


def check_against_truth(blocks, got):
    first, travel, vib = truth_arrays(blocks)
    for b in got:
        k = b.first_sample_index - first
        assert np.max(np.abs(b.travel - travel[k:k + b.travel.size])) <= SCALING.travel_lsb_rad / 2 + 1e-12
        assert np.max(np.abs(b.vibration - vib[k:k + b.travel.size])) <= SCALING.vibration_lsb_g / 2 + 1e-9
        assert b.sample_rate == 128000.0


@pytest.mark.parametrize("link", ["pty", "tcp"])
def test_clean_stream_arrives_complete_and_exact(stream_blocks, link):
    drv, em, got = asyncio.run(run_chain(stream_blocks, link))
    assert isinstance(drv, Driver)
    check_against_truth(stream_blocks, got)
    assert sum(b.travel.size for b in got) == sum(b.travel.size for b in stream_blocks)
    assert drv.stats.frames == em.stats.frames_sent
    assert (drv.stats.crc_errors, drv.stats.dropped_frames, drv.stats.gaps) == (0, 0, 0)
    assert not any(b.flags for b in got)


@pytest.mark.parametrize("link", ["pty", "tcp"])
def test_every_injected_fault_is_counted(stream_blocks, link):
    faults = FaultPlan(corrupt={5, 30}, drop={10, 11, 40}, garbage={20, 50})
    drv, em, got = asyncio.run(run_chain(stream_blocks, link, faults))
    es, ds = em.stats, drv.stats
    assert (es.corrupted_frames, es.dropped_frames, es.garbage_bursts) == (2, 3, 2)
    assert ds.crc_errors == es.corrupted_frames
    assert ds.dropped_frames == es.dropped_frames + es.corrupted_frames  # a corrupt frame is lost too
    assert ds.frames == es.frames_sent - es.corrupted_frames
    assert ds.resyncs >= es.garbage_bursts
    check_against_truth(stream_blocks, got)
    # Four runs of lost frames (5, 10-11, 30, 40): four blocks flagged, each after an index jump.
    flagged = [b for b in got if GAP_FLAG in b.flags]
    assert ds.gaps == len(flagged) == 4
    ends = {b.end_index for b in got}
    assert all(b.first_sample_index not in ends for b in flagged)
    lost = sum(b.travel.size for b in stream_blocks) - sum(b.travel.size for b in got)
    assert lost == 256 * ds.dropped_frames


def test_disconnect_leads_to_a_reconnect_and_the_stream_goes_on(stream_blocks):
    # Real-time pace: pyserial flushes its input when it reopens a port, so frames sent in
    # that instant are lost (and flagged); an unthrottled emulator could lose all the rest.
    drv, em, got = asyncio.run(run_chain(stream_blocks, "tcp", FaultPlan(disconnect={15}), speed=1.0))
    assert em.stats.disconnects == 1 and em.stats.connections == 2
    assert drv.stats.reconnects == 1
    check_against_truth(stream_blocks, got)
    assert got[-1].end_index == stream_blocks[-1].end_index
    # Anything lost in the disconnect is visible: every index jump is flagged.
    for prev, b in zip(got, got[1:]):
        assert b.first_sample_index == prev.end_index or GAP_FLAG in b.flags


def test_driver_keeps_trying_until_the_port_appears(stream_blocks):
    probe = socket.create_server(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # nothing listens yet: the driver must back off and retry

    async def main():
        drv = SerialStreamDriver(SerialSettings(f"socket://127.0.0.1:{port}", reconnect_min_s=0.01,
                                                reconnect_max_s=0.05))
        aiter = drv.__aiter__()
        await asyncio.sleep(0.1)
        assert not drv.stats.connected
        em = SerialDaqEmulator(stream_blocks[:4], port=port, speed=1.0).start()  # see above
        try:
            block = await asyncio.wait_for(aiter.__anext__(), timeout=10)
        finally:
            await drv.aclose()
            em.close()
        return block, drv.stats.reconnects

    block, drv_reconnects = asyncio.run(main())
    assert block.first_sample_index < stream_blocks[3].end_index and drv_reconnects == 0


def test_a_malformed_url_is_an_error_not_a_retry_loop():
    async def main():
        drv = SerialStreamDriver(SerialSettings("nosuchscheme://x"))
        try:
            with pytest.raises(DriverError, match="nosuchscheme"):
                async for _ in drv:
                    pass
        finally:
            await drv.aclose()

    asyncio.run(main())


def test_settings_refuse_nonsense():
    with pytest.raises(ValueError, match="device path"):
        SerialSettings("")
    with pytest.raises(ValueError, match="reconnect"):
        SerialSettings("/dev/ttyACM0", reconnect_min_s=2, reconnect_max_s=1)
