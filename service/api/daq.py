"""The acquisition loop of ``hvcb serve``: driver → trigger → durable COMTRADE → ``Monitor.ingest``.

The driver is built here, at the edge, from the ``[acquisition]`` settings; nothing below reads
settings. The loop runs on its own thread and event loop. Every ``status_interval_s`` the
driver's counters (connected, frames, dropped frames, CRC errors, captures) are stored in
``daq_status``, which ``/healthz``, ``/metrics`` and the SCADA points read.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from pathlib import Path

from sqlalchemy.exc import DBAPIError, OperationalError

from service.storage import crud

log = logging.getLogger("hvcb.daq")


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


class DaqRunner:
    """Runs one DAQ's acquisition loop in a background thread of the service."""

    def __init__(self, settings, Session, monitor):
        self.settings, self.Session, self.monitor = settings, Session, monitor
        self.acq = settings.acquisition
        self.driver = None
        self.breaker_id: int | None = None
        self.captures = 0
        self.error: str | None = None
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._started = threading.Event()

    @property
    def enabled(self) -> bool:
        return self.acq.driver != "none"

    def start(self) -> None:
        if not self.enabled:
            return
        with self.Session() as session:
            rows = crud.list_breakers(session)
            row = next((r for r in rows if r.name == self.acq.breaker), None) if self.acq.breaker else \
                (rows[0] if rows else None)
            if row is None:
                raise ValueError(f"[acquisition] breaker {self.acq.breaker or '(first)'!r} is not registered; "
                                 f"list its breaker file under `breakers`")
            self.breaker_id, self.breaker = row.id, crud.breaker_model(row)
        self.out_dir = Path(self.settings.capture_dir) / "daq" / row.name
        self._thread = threading.Thread(target=self._run, name="hvcb-daq", daemon=True)
        self._thread.start()
        self._started.wait(10)

    def stop(self) -> None:
        if self._thread is None:
            return
        if self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(timeout=15)
        self._thread = None

    def connected(self) -> bool:
        return bool(self.driver is not None and self.driver.stats.connected)

    # -- the loop ------------------------------------------------------------------------------
    def _run(self) -> None:
        self._loop = asyncio.new_event_loop()
        try:
            self._loop.run_until_complete(self._main())
        finally:
            self._loop.close()

    async def _main(self) -> None:
        from service.acquisition.pipeline import capture_stream
        from service.acquisition.trigger import TriggerSettings

        self._stop = asyncio.Event()
        try:  # built inside this loop: async clients bind to the loop that creates them
            self.driver = make_driver(self.acq, self.breaker)
        except Exception as exc:
            self.error = f"cannot build the {self.acq.driver} driver: {exc}"
            log.error("%s", self.error)
            return
        finally:
            self._started.set()

        async def on_capture(cfg_path, detected):
            await asyncio.to_thread(self._ingest, cfg_path, detected)

        pipeline = asyncio.create_task(capture_stream(self.driver, TriggerSettings.from_breaker(self.breaker),
                                                      self.out_dir, on_capture=on_capture))
        status = asyncio.create_task(self._status_loop())
        stopper = asyncio.create_task(self._stop.wait())
        try:
            done, _ = await asyncio.wait({pipeline, stopper}, return_when=asyncio.FIRST_COMPLETED)
            if pipeline in done and pipeline.exception() is not None:
                exc = pipeline.exception()
                self.error = f"{type(exc).__name__}: {exc}"
                log.error("acquisition stopped: %s", self.error)
            elif pipeline in done:
                log.info("the DAQ stream ended (%d captures)", self.captures)
        finally:
            for task in (pipeline, stopper):
                task.cancel()
            await asyncio.gather(pipeline, stopper, return_exceptions=True)
            close = getattr(self.driver, "aclose", None)
            if close is not None:
                try:
                    await close()
                except Exception:  # already closed by the pipeline
                    pass
            status.cancel()
            await asyncio.gather(status, return_exceptions=True)
            await asyncio.to_thread(self._report, False)

    def _ingest(self, cfg_path, detected) -> None:
        result = self.monitor.ingest(detected.capture, breaker_id=self.breaker_id, operation=detected.operation,
                                     source="daq", capture_path=cfg_path)
        self.captures += 1
        log.info("captured %s (%s): operation %s", Path(cfg_path).name, detected.operation,
                 result.operation_id if result.operation_id is not None else "spooled")

    async def _status_loop(self) -> None:
        while True:
            await asyncio.to_thread(self._report, None)
            await asyncio.sleep(self.acq.status_interval_s)

    def _report(self, connected: bool | None) -> None:
        if self.driver is None:
            return
        st = self.driver.stats
        try:
            with self.Session() as session, session.begin():
                crud.report_daq(session, breaker_id=self.breaker_id,
                                connected=st.connected if connected is None else connected,
                                frames=st.frames, frames_dropped=st.dropped_frames, crc_errors=st.crc_errors,
                                captures=max(st.captures, self.captures),
                                detail=self.error or f"{self.acq.driver} driver; {st.reconnects} reconnects, "
                                                     f"{st.retries} retries, {st.abandoned} abandoned downloads")
        except (OperationalError, DBAPIError):
            pass  # the database is down: the captures are spooled, the status waits
