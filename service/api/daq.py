"""The DAQs of ``hvcb serve``: each ``[[acquisition]]`` entry → driver → trigger → durable
COMTRADE → ``Monitor.ingest`` under its breaker.

The drivers are built here, at the edge, from the settings; the supervised loops live in
``service.acquisition.daq_runner``. Every ``status_interval_s`` each DAQ's counters are stored
in ``daq_status`` (SCADA points and remote readers); ``states()`` is the live per-DAQ health
that ``/healthz`` and ``/metrics`` read.
"""

from __future__ import annotations

import logging
from pathlib import Path

from sqlalchemy.exc import DBAPIError, OperationalError

from service.acquisition.daq_runner import DaqGroup, DaqRunner, DaqState
from service.storage import crud

log = logging.getLogger("hvcb.daq")


class ServiceDaqs:
    """Every DAQ this service listens to, each ingesting into its own breaker."""

    def __init__(self, settings, Session, monitor):
        self.settings, self.Session, self.monitor = settings, Session, monitor
        self.group = DaqGroup([])
        self.breaker_ids: dict[str, int] = {}

    @property
    def enabled(self) -> bool:
        return bool(self.settings.acquisition)

    @property
    def drivers(self) -> list[str]:
        return [a.driver for a in self.settings.acquisition]

    def start(self) -> None:
        """Resolve each entry's breaker, then start every DAQ. An unregistered breaker is a
        settings error (raised before anything starts)."""
        runners = []
        with self.Session() as session:
            rows = crud.list_breakers(session)
            for acq in self.settings.acquisition:
                row = next((r for r in rows if r.name == acq.breaker), None) if acq.breaker else \
                    (rows[0] if rows else None)
                if row is None:
                    raise ValueError(f"[[acquisition]] breaker {acq.breaker or '(first)'!r} is not registered; "
                                     f"list its breaker file under `breakers`")
                name = acq.name or row.name
                self.breaker_ids[name] = row.id
                runners.append(DaqRunner(acq, crud.breaker_model(row),
                                         Path(self.settings.capture_dir) / "daq" / row.name, name=name,
                                         on_capture=self._ingest_for(row.id, name),
                                         on_status=self._report_for(row.id)))
        if runners:  # a DAQ removed from the settings leaves no stale "disconnected" status behind
            with self.Session() as session, session.begin():
                crud.forget_daqs_except(session, breaker_ids=list(self.breaker_ids.values()))
        self.group = DaqGroup(runners)
        self.group.start()

    def stop(self) -> None:
        self.group.stop()

    def states(self) -> list[DaqState]:
        return self.group.states()

    def _ingest_for(self, breaker_id: int, name: str):
        def ingest(cfg_path, detected) -> None:
            result = self.monitor.ingest(detected.capture, breaker_id=breaker_id, operation=detected.operation,
                                         source="daq", capture_path=cfg_path)
            log.info("DAQ %s captured %s (%s): operation %s", name, Path(cfg_path).name, detected.operation,
                     result.operation_id if result.operation_id is not None else "spooled")
        return ingest

    def _report_for(self, breaker_id: int):
        def report(st: DaqState) -> None:
            try:
                with self.Session() as session, session.begin():
                    crud.report_daq(session, breaker_id=breaker_id, connected=st.up, frames=st.frames,
                                    frames_dropped=st.frames_dropped, crc_errors=st.crc_errors,
                                    captures=st.captures,
                                    detail=st.error or f"{st.driver} driver {st.state}; {st.reconnects} reconnects, "
                                                       f"{st.retries} retries, {st.abandoned} abandoned downloads, "
                                                       f"{st.restarts} restarts")
            except (OperationalError, DBAPIError):
                pass  # the database is down: the captures are spooled, the status waits
        return report
