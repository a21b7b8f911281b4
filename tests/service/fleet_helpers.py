"""Parts for the fleet tests: breaker files for several bays, a Modbus DAQ emulator on its own
thread, a central hvcb served by uvicorn that can be stopped and started again, and a fit
double that skips the fit (these tests are about where captures go, not about fits)."""

from __future__ import annotations

import asyncio
import shutil
import threading
import time
from pathlib import Path

import numpy as np

from conftest import BREAKER_FILE
from tests.live_server import LiveServer, free_port  # noqa: F401 (free_port: the tests' import)


def no_fit(capture, breaker, operation, *, dc=None, seed=1):
    """Fit double: fails at once, so a test's fit jobs cost nothing."""
    from service.estimation import FitError

    raise FitError("not fitted in this test")


def breaker_files(directory: Path, names: list[str]) -> list[Path]:
    """Copies of the reference breaker file under other names (one per bay)."""
    directory.mkdir(parents=True, exist_ok=True)
    shutil.copy(BREAKER_FILE.with_name("reference-252kV.cam.csv"), directory)
    text = BREAKER_FILE.read_text()
    out = []
    for name in names:
        p = directory / f"{name}.toml"
        p.write_text(text.replace('name = "reference-252kV"', f'name = "{name}"'))
        out.append(p)
    return out


def poll(fn, timeout: float, what: str, every: float = 0.1):
    """fn() until it returns something truthy; AssertionError naming ``what`` after ``timeout``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = fn()
        if value:
            return value
        time.sleep(every)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def capture_block(breaker, kind: str, seed: int, first_index: int):
    """One synthetic operation as a DAQ-triggered capture block (distinct noise per seed)."""
    from drivers.interface import SampleBlock
    from drivers.synthetic import synthesize_capture

    cap, _ = synthesize_capture(breaker, kind, breaker.design_parameters(), rng=np.random.default_rng(seed))
    return SampleBlock(first_index, cap.travel, cap.vibration, cap.sample_rate)


class ModbusDaq:
    """``ModbusDaqEmulator`` on its own thread and event loop; ``add`` queues a capture, ``kill``
    shuts its server (the DAQ vanishes from the network)."""

    def __init__(self, breaker, port: int = 0):
        from drivers.emulators.modbus_daq import ModbusDaqEmulator
        from drivers.scaling import ChannelScaling

        self.emulator = ModbusDaqEmulator([], transport="tcp", port=port,
                                          scaling=ChannelScaling.from_breaker(breaker))
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, name="test-modbus-daq", daemon=True)
        self.thread.start()
        asyncio.run_coroutine_threadsafe(self.emulator.start(), self.loop).result(20)
        self.port = self.emulator.port

    def add(self, block) -> None:
        async def add():
            self.emulator.add_capture(block)
        asyncio.run_coroutine_threadsafe(add(), self.loop).result(10)

    @property
    def acknowledged(self) -> int:
        return self.emulator.stats.captures_acknowledged

    def kill(self) -> None:
        if self.loop.is_running():
            asyncio.run_coroutine_threadsafe(self.emulator.stop(), self.loop).result(20)
            self.loop.call_soon_threadsafe(self.loop.stop)
            self.thread.join(timeout=10)
            self.loop.close()


class Central:
    """A central hvcb (the app factory under uvicorn) on a fixed port, stopped and started at will."""

    def __init__(self, settings):
        self.settings = settings
        self.port = settings.port
        self.url = f"http://127.0.0.1:{self.port}"
        self.live: LiveServer | None = None
        self.admin_key: str | None = None

    def start(self) -> None:
        from service.api.app import create_app

        shown = []
        app = create_app(self.settings, on_key=shown.append)
        self.live = LiveServer(app, port=self.port, name="test-central").start()
        if shown:
            self.admin_key = shown[0]
        self.app = app

    def stop(self) -> None:
        if self.live is not None:
            self.live.stop()
            self.live = None
