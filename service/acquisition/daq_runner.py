"""Many DAQs, each supervised on its own: driver → trigger → durable COMTRADE → ``on_capture``.

Used by ``hvcb serve`` (captures go to the monitor) and ``hvcb agent`` (captures go to the
outbox). Each DAQ runs on its own thread and event loop, so a slow or failing one never holds
the others up. A driver that cannot be built, raises, or whose stream ends is rebuilt after a
wait that doubles from ``retry_min_s`` to ``retry_max_s`` (reset once the DAQ delivers data).
A replay driver that reaches the end of its files is ``finished``, not restarted (that would
store the same captures again).

``DaqState`` is the one record of a DAQ's health: ``/healthz``, ``/metrics``, the agent's
metrics and the web pages all read ``DaqGroup.states()``.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from drivers.backoff import Backoff
from service.errors import in_words

log = logging.getLogger("hvcb.daq")

STATES = ("starting", "running", "retrying", "finished", "stopped")


def utcnow() -> datetime:
    return datetime.now(timezone.utc)


def make_driver(acq, breaker):
    """The driver described by ``acq`` (``AcquisitionSettings``) for ``breaker``."""
    from drivers.scaling import ChannelScaling

    scaling = ChannelScaling.from_breaker(breaker)
    if acq.driver == "serial":
        from drivers.serial_stream import SerialSettings, SerialStreamDriver

        s = acq.serial
        return SerialStreamDriver(SerialSettings(url=s.url, baudrate=s.baudrate, reconnect_min_s=s.reconnect_min_s,
                                                 reconnect_max_s=s.reconnect_max_s), scaling)
    if acq.driver == "modbus":
        from drivers.modbus import ModbusCaptureDriver, ModbusSettings

        m = acq.modbus
        return ModbusCaptureDriver(ModbusSettings(transport=m.transport, host=m.host, port=m.port, url=m.url,
                                                  baudrate=m.baudrate, device_id=m.device_id, timeout_s=m.timeout_s,
                                                  poll_interval_s=m.poll_interval_s, block_retries=m.block_retries),
                                   scaling)
    if acq.driver == "replay":
        from drivers.replay import ReplayDriver

        return ReplayDriver([str(p) for p in acq.replay.files], speed=acq.replay.speed)
    raise ValueError(f"no driver for acquisition driver {acq.driver!r}")


def _analyser_records(acq) -> list:
    """The replay files when they are all breaker-analyser exports (recognised by content)."""
    if acq.driver != "replay":
        return []
    from drivers.analyser import looks_like_analyser
    from drivers.capture_file import sniff_text

    files = [Path(p) for p in acq.replay.files]
    for f in files:
        if f.suffix.lower() in (".cfg", ".cff", ".dat"):
            return []
        text, _ = sniff_text(f, None)
        if text is None or not looks_like_analyser(text):
            return []
    return files


@dataclass
class DaqState:
    """What one DAQ is doing now (a snapshot; times UTC).

    ``up`` is true while the driver runs and its link is connected. ``restarts`` counts driver
    rebuilds after a failure; ``error`` is the last failure in words.
    """

    name: str
    breaker: str
    driver: str
    state: str = "starting"
    connected: bool = False
    error: str | None = None
    restarts: int = 0
    captures: int = 0
    capture_errors: int = 0
    frames: int = 0
    frames_dropped: int = 0
    crc_errors: int = 0
    reconnects: int = 0
    retries: int = 0
    abandoned: int = 0
    last_capture_at: datetime | None = None
    next_retry_at: datetime | None = None
    since: datetime = field(default_factory=utcnow)

    @property
    def up(self) -> bool:
        return self.state == "running" and self.connected

    @property
    def down(self) -> bool:
        """Failing or disconnected (a replay has no link: it is down only while failing)."""
        return self.state == "retrying" or (self.state == "running" and not self.connected
                                            and self.driver != "replay")

    def to_dict(self) -> dict:
        d = asdict(self)
        for k in ("last_capture_at", "next_retry_at", "since"):
            if d[k] is not None:
                d[k] = d[k].isoformat().replace("+00:00", "Z")
        d["up"], d["down"] = self.up, self.down
        return d


class DaqRunner:
    """One DAQ's supervised acquisition loop on a background thread.

    ``on_capture(cfg_path, detected)`` is called on a worker thread after the capture's files
    are durable; an exception there is logged and counted, never fatal to the DAQ.
    ``on_status(state)`` is called every ``acq.status_interval_s`` and once at the end.
    """

    def __init__(self, acq, breaker, out_dir: str | Path, *, on_capture: Callable, name: str | None = None,
                 on_status: Callable | None = None, clock: Callable[[], datetime] = utcnow):
        self.acq, self.breaker, self.out_dir = acq, breaker, Path(out_dir)
        self.on_capture, self.on_status, self.clock = on_capture, on_status, clock
        self.name = name or acq.name or breaker.name
        self.driver = None
        self._state = DaqState(name=self.name, breaker=breaker.name, driver=acq.driver)
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._started = threading.Event()

    # -- lifecycle -----------------------------------------------------------------------------
    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name=f"hvcb-daq-{self.name}", daemon=True)
        self._thread.start()
        self._started.wait(10)

    def stop(self) -> None:
        if self._thread is None:
            return
        if self._loop is not None and self._stop is not None:
            try:
                self._loop.call_soon_threadsafe(self._stop.set)
            except RuntimeError:  # the loop already ended
                pass
        self._thread.join(timeout=15)
        self._thread = None

    def state(self) -> DaqState:
        """A copy of the current state, with the driver's counters."""
        with self._lock:
            st = DaqState(**{k: getattr(self._state, k) for k in self._state.__dataclass_fields__})
        d = self.driver
        if d is not None:
            s = d.stats
            st.connected = bool(s.connected) and st.state == "running"
            st.frames, st.frames_dropped, st.crc_errors = s.frames, s.dropped_frames, s.crc_errors
            st.reconnects, st.retries, st.abandoned = s.reconnects, s.retries, s.abandoned
        else:
            st.connected = False
        return st

    def _set(self, **kw) -> None:
        with self._lock:
            if "state" in kw and kw["state"] != self._state.state:
                kw.setdefault("since", utcnow())
            for k, v in kw.items():
                setattr(self._state, k, v)

    # -- the loop ------------------------------------------------------------------------------
    def _run(self) -> None:
        self._loop = asyncio.new_event_loop()
        try:
            self._loop.run_until_complete(self._main())
        finally:
            self._loop.close()

    async def _main(self) -> None:
        self._stop = asyncio.Event()
        self._started.set()
        status = asyncio.create_task(self._status_loop())
        try:
            await self._supervise()
        finally:
            status.cancel()
            await asyncio.gather(status, return_exceptions=True)
            if self._state.state not in ("finished",):
                self._set(state="stopped")
            await asyncio.to_thread(self._report)

    async def _supervise(self) -> None:
        acq = self.acq
        backoff = Backoff(acq.retry_min_s, acq.retry_max_s)
        run_no = 0
        while not self._stop.is_set():
            run_no += 1
            outcome = await self._run_once(run_no)
            if outcome in ("stopped", "finished"):
                return
            productive, error = outcome
            if productive:
                backoff.reset()
            wait = backoff.next()
            with self._lock:
                restarts = self._state.restarts + 1
            self._set(state="retrying", error=error, restarts=restarts,
                      next_retry_at=utcnow() + _seconds(wait))
            log.warning("DAQ %s (%s): %s; rebuilding the driver in %.1f s", self.name, acq.driver, error, wait)
            try:
                await asyncio.wait_for(self._stop.wait(), wait)
            except TimeoutError:
                pass

    async def _run_once(self, run_no: int):
        """One driver's life. Returns "stopped", "finished" or (productive, error)."""
        from service.acquisition.pipeline import capture_stream
        from service.acquisition.trigger import TriggerSettings

        self._set(state="starting", next_retry_at=None)
        try:  # built inside this loop: async clients bind to the loop that creates them
            self.driver = make_driver(self.acq, self.breaker)
        except Exception as exc:
            return False, f"cannot build the {self.acq.driver} driver: {exc}"
        self._set(state="running")
        captures_before = self._state.captures
        # One file prefix per run: a driver restarted from sample 0 never overwrites earlier files.
        prefix = f"op-{utcnow():%Y%m%dT%H%M%S}-{run_no}"

        inflight: set = set()

        async def on_capture(cfg_path, detected):
            # Shielded: a stop waits for a capture being handed on rather than abandoning it.
            fut = asyncio.ensure_future(asyncio.to_thread(self._deliver, cfg_path, detected))
            inflight.add(fut)
            try:
                await asyncio.shield(fut)
            finally:
                if fut.done():
                    inflight.discard(fut)

        records = _analyser_records(self.acq)
        if records:  # breaker-analyser exports: whole records, operations found from the coils
            from service.acquisition.pipeline import capture_records

            work = capture_records(records, self.breaker, self.out_dir, on_capture=on_capture, prefix=prefix)
        else:
            work = capture_stream(self.driver, TriggerSettings.from_breaker(self.breaker), self.out_dir,
                                  on_capture=on_capture, prefix=prefix, clock=self.clock)
        pipeline = asyncio.create_task(work)
        stopper = asyncio.create_task(self._stop.wait())
        driver = self.driver
        close = getattr(driver, "aclose", None)
        try:
            await asyncio.wait({pipeline, stopper}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            if not pipeline.done() and close is not None:
                # Close the driver first: a client library may swallow a cancellation mid-read
                # and poll on; a closed driver ends its iteration whatever it was doing.
                try:
                    await close()
                except Exception:
                    pass
            for task in (pipeline, stopper):
                task.cancel()
            _, pending = await asyncio.wait({pipeline, stopper}, timeout=10)
            if pending:
                log.error("DAQ %s: the %s driver did not stop within 10 s", self.name, self.acq.driver)
            if inflight:
                await asyncio.wait(inflight, timeout=30)
            if close is not None:
                try:
                    await close()
                except Exception:  # already closed
                    pass
        if self._stop.is_set():
            return "stopped"
        productive = self._state.captures > captures_before or driver.stats.frames > 0 \
            or driver.stats.captures > 0
        if not pipeline.done():
            return productive, "the driver did not stop"
        exc = pipeline.exception() if not pipeline.cancelled() else None
        if exc is not None:
            return productive, in_words(exc)
        if self.acq.driver == "replay":
            self._set(state="finished", error=None)
            log.info("DAQ %s: the replay ended (%d captures)", self.name, self._state.captures)
            return "finished"
        return productive, "the DAQ stream ended"

    def _deliver(self, cfg_path, detected) -> None:
        try:
            self.on_capture(cfg_path, detected)
        except Exception as exc:
            with self._lock:
                self._state.capture_errors += 1
            log.error("DAQ %s: capture %s was written but not handed on: %s", self.name, Path(cfg_path).name, exc)
            return
        with self._lock:
            self._state.captures += 1
            self._state.last_capture_at = utcnow()
            self._state.error = None

    async def _status_loop(self) -> None:
        while True:
            await asyncio.to_thread(self._report)
            await asyncio.sleep(self.acq.status_interval_s)

    def _report(self) -> None:
        if self.on_status is None:
            return
        try:
            self.on_status(self.state())
        except Exception as exc:  # a status store that is down must not stop acquisition
            log.debug("DAQ %s: status not stored: %s", self.name, exc)


def _seconds(s: float):
    from datetime import timedelta

    return timedelta(seconds=s)


class DaqGroup:
    """Every configured DAQ, each on its own supervised runner."""

    def __init__(self, runners: list[DaqRunner]):
        self.runners = list(runners)

    @property
    def enabled(self) -> bool:
        return bool(self.runners)

    def start(self) -> None:
        for r in self.runners:
            r.start()

    def stop(self) -> None:
        for r in self.runners:
            r.stop()

    def states(self) -> list[DaqState]:
        return [r.state() for r in self.runners]

    def all_up(self) -> bool:
        return all(s.up for s in self.states())
