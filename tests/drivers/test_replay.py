"""Replay: sources (blocks, captures, CSV streams, COMTRADE) and pacing with an injected clock."""

import asyncio

import numpy as np
import pytest

from drivers import replay
from drivers.interface import Driver, SampleBlock
from drivers.replay import NO_VIBRATION_FLAG, ReplayDriver
from drivers.capture import Capture


class FakeClock:
    """A clock that only moves when the driver sleeps."""

    def __init__(self):
        self.now = 100.0
        self.sleeps = []

    def __call__(self):
        return self.now

    async def sleep(self, seconds):
        self.sleeps.append(seconds)
        self.now += seconds


def collect(driver, clock=None):
    async def main():
        out = []
        async for block in driver:
            out.append((block, clock.now if clock else None))
        await driver.aclose()
        return out

    return asyncio.run(main())


def blocks(n_blocks=5, size=1000, fs=1000.0):
    rng = np.random.default_rng(0)
    return [SampleBlock(k * size, rng.normal(size=size), rng.normal(size=size), fs) for k in range(n_blocks)]


@pytest.mark.parametrize("speed", [1.0, 4.0])
def test_pacing_releases_each_block_when_its_last_sample_exists(speed):
    clock = FakeClock()
    drv = ReplayDriver(blocks(), speed=speed, clock=clock, sleep=clock.sleep)
    assert isinstance(drv, Driver)
    out = collect(drv, clock)
    for block, released_at in out:
        assert released_at == pytest.approx(100.0 + block.end_index / 1000.0 / speed)
    assert sum(clock.sleeps) == pytest.approx(5.0 / speed)
    assert drv.stats.samples == 5000


def test_as_fast_as_possible_never_sleeps():
    clock = FakeClock()
    out = collect(ReplayDriver(blocks(), speed=None, clock=clock, sleep=clock.sleep), clock)
    assert len(out) == 5 and clock.sleeps == []


def test_a_slow_consumer_is_not_made_to_wait_again():
    clock = FakeClock()
    drv = ReplayDriver(blocks(), speed=1.0, clock=clock, sleep=clock.sleep)

    async def main():
        await drv.__anext__()
        clock.now += 10.0  # the consumer spent 10 s elsewhere: the rest is overdue
        return [b async for b in drv]

    assert len(asyncio.run(main())) == 4 and len(clock.sleeps) == 1


def test_large_blocks_are_split_to_the_block_size():
    out = [b for b, _ in collect(ReplayDriver(blocks(2, 1000), block_samples=300, speed=None))]
    assert [b.travel.size for b in out] == [300, 300, 300, 100] * 2
    assert [b.first_sample_index for b in out][:5] == [0, 300, 600, 900, 1000]


def test_captures_play_one_after_another_without_overlapping_indices():
    cap = Capture(travel=np.arange(1000.0), sample_rate=128000.0, vibration=None)
    out = [b for b, _ in collect(ReplayDriver([cap, cap], block_samples=400, speed=None))]
    assert [b.first_sample_index for b in out] == [0, 400, 800, 1000, 1400, 1800]
    assert all(NO_VIBRATION_FLAG in b.flags and not b.vibration.any() for b in out)
    assert np.array_equal(np.concatenate([b.travel for b in out[:3]]), cap.travel)


def test_long_csv_stream_is_read_in_chunks(tmp_path, monkeypatch):
    monkeypatch.setattr(replay, "CSV_CHUNK_ROWS", 333)  # force many chunks
    n, fs = 2500, 128000.0
    t = np.arange(n) / fs
    travel, vib = np.sin(t * 100), np.cos(t * 100)
    path = tmp_path / "stream.csv"
    np.savetxt(path, np.column_stack([t, travel, vib]), delimiter=",", header="t_s,travel_rad,vibration_g",
               comments="", fmt="%.10g")
    out = [b for b, _ in collect(ReplayDriver(path, block_samples=1000, speed=None))]
    assert [b.travel.size for b in out] == [1000, 1000, 500]
    assert out[0].sample_rate == pytest.approx(fs)
    assert np.allclose(np.concatenate([b.travel for b in out]), travel, atol=1e-9)
    assert np.allclose(np.concatenate([b.vibration for b in out]), vib, atol=1e-9)


def test_comtrade_capture_replays(tmp_path):
    cfg = "\n".join(["station,daq,1999", "2,2A,0D",
                     "1,travel,,,rad,0.001,0,0,-32767,32767,1,1,P",
                     "2,vibration,,,g,0.1,0,0,-32767,32767,1,1,P",
                     "50", "1", "1000,4", "01/01/2024,00:00:00.000000", "01/01/2024,00:00:00.000000",
                     "ASCII", "1"]) + "\n"
    dat = "".join(f"{k + 1},{k * 1000},{k * 10},{-k * 5}\n" for k in range(4))
    (tmp_path / "op.cfg").write_text(cfg)
    (tmp_path / "op.dat").write_text(dat)
    out = [b for b, _ in collect(ReplayDriver(tmp_path / "op.cfg", speed=None))]
    assert len(out) == 1 and out[0].sample_rate == 1000.0
    assert out[0].travel == pytest.approx([0.0, 0.01, 0.02, 0.03])
    assert out[0].vibration == pytest.approx([0.0, -0.5, -1.0, -1.5])


def test_async_iterable_source_and_bad_input():
    async def gen():
        for b in blocks(3):
            yield b

    assert len(collect(ReplayDriver(gen(), speed=None))) == 3
    with pytest.raises(ValueError, match="speed"):
        ReplayDriver(blocks(), speed=0)
    with pytest.raises(TypeError, match="cannot play"):
        collect(ReplayDriver([42], speed=None))
