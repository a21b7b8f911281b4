"""The app factory. Nothing is built at import time: tests and commands pass their own settings."""

from __future__ import annotations

import logging
import os
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import Depends, FastAPI, Request
from fastapi.responses import JSONResponse, Response
from sqlalchemy import select
from sqlalchemy.exc import DBAPIError, OperationalError

from service.settings import Settings
from service.storage import crud
from service.storage.db import current_revision, head_revision, make_engine, session_factory

from .deps import KeyCache, require
from .metrics import build_registry, render

log = logging.getLogger("hvcb.api")


class NotMigrated(RuntimeError):
    pass


def check_schema(engine) -> None:
    have, want = current_revision(engine), head_revision()
    if have != want:
        raise NotMigrated(f"the database is at migration {have or 'none'}, this code needs {want}: "
                          f"run `hvcb migrate` (hvcb serve and hvcb demo do it for you)")


def bootstrap(settings: Settings, Session) -> str | None:
    """Register the configured breakers; create the first admin key if there is none.

    Returns the new admin key (shown once; also written to ``<data_dir>/admin.key`` with mode
    0600) or None when keys already exist.
    """
    with Session() as session, session.begin():
        for path in settings.breakers:
            name = crud.register_breaker_file(session, path=Path(path), tag=None)
            tag = settings.tags.get(name.name)
            if tag and name.tag != tag:
                name.tag = tag
        if crud.count_api_keys(session):
            return None
        _, key = crud.create_api_key(session, name="admin (generated at first start)", role="admin",
                                     key=settings.bootstrap_admin_key)
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    fd = os.open(settings.key_file, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as fh:
        fh.write(key + "\n")
    os.chmod(settings.key_file, 0o600)
    return key


def create_app(settings: Settings, *, executor=None, start_monitor: bool = True, on_key=None) -> FastAPI:
    """Build the service. ``executor`` replaces the configured one (tests); ``on_key(key)`` is
    called with a newly generated admin key (the commands print it)."""
    from service.jobs.ingest import Monitor
    from service.workers import make_executor
    from service.workers.diagnoses import DiagnosisRunner

    from .daq import ServiceDaqs

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        engine = make_engine(settings.sqlalchemy_url)
        check_schema(engine)
        Session = session_factory(engine)
        key = bootstrap(settings, Session)
        if key and on_key:
            on_key(key)
        ex = executor or make_executor(settings, on_result=lambda r: app.state.metrics_local.observe(r))
        monitor = Monitor(settings, Session, ex)
        daq = ServiceDaqs(settings, Session, monitor)
        app.state.engine, app.state.Session, app.state.monitor, app.state.daq = engine, Session, monitor, daq
        app.state.diagnoses = DiagnosisRunner(settings.sqlalchemy_url)
        if start_monitor:
            monitor.start()
            try:
                daq.start()
            except Exception:
                monitor.stop()
                raise
        from service.storage.retention import RetentionSchedule

        app.state.retention = RetentionSchedule(settings, Session)  # [retention]: prunes raw captures
        if start_monitor:
            app.state.retention.start()
        app.state.iec61850 = None
        if settings.iec61850_port:
            from service.iec61850.server import Iec61850Server

            try:
                app.state.iec61850 = Iec61850Server(settings, Session)
                app.state.iec61850.start()
            except Exception:
                app.state.retention.stop()
                if start_monitor:
                    daq.stop()
                    monitor.stop()
                raise
        try:
            yield
        finally:
            app.state.retention.stop()
            if app.state.iec61850 is not None:
                app.state.iec61850.stop()
            app.state.diagnoses.shutdown()
            if start_monitor:
                daq.stop()
                monitor.stop()
            else:
                ex.shutdown(wait=False)
            engine.dispose()

    app = FastAPI(title="hvcb", version="1", lifespan=lifespan,
                  description="Condition monitor for spring-operated HV circuit-breaker mechanisms. "
                              "Send an API key in X-API-Key. Times are UTC ISO-8601 with Z.")
    app.state.settings = settings
    app.state.key_cache = KeyCache()
    app.state.metrics_registry, app.state.metrics_local = build_registry(app)

    from .routes import router
    from .routes_alarms import router as alarm_router

    app.include_router(alarm_router)  # first: its paths never overlap the main router's
    app.include_router(router)

    from service.web import mount_web  # the engineers' web page at /

    mount_web(app)

    @app.exception_handler(OperationalError)
    @app.exception_handler(DBAPIError)
    async def _db_down(request: Request, exc: Exception):
        log.warning("database error on %s: %s", request.url.path, exc.__class__.__name__)
        return JSONResponse({"detail": "database unavailable; try again shortly"}, status_code=503)

    @app.get("/healthz", tags=["service"])
    def healthz(request: Request):
        """Liveness (open: no key needed). Says whether the database answers and the DAQs are connected.

        ``daqs``: this service's DAQs (``[[acquisition]]``), each with its state (starting, running,
        retrying, finished, stopped), ``up``, ``down``, last error, restarts and counters;
        ``daq_connected``: true when every one is up, null when none is configured; ``daq`` lists
        every breaker's last reported DAQ status (also remote ones). Any DAQ down: ``degraded``.
        """
        from datetime import timedelta

        from service.storage.models import utcnow

        monitor, daq = request.app.state.monitor, request.app.state.daq
        states = daq.states() if daq.enabled else []
        drivers = daq.drivers
        out = {"status": "ok", "database": "ok", "spooled_captures": len(monitor.spool),
               "daq_connected": all(st.up for st in states) if daq.enabled and states else
               (False if daq.enabled else None),
               "daq_driver": drivers[0] if len(drivers) == 1 else ("none" if not drivers else "multi"),
               "daqs": [st.to_dict() for st in states], "daq": []}
        errors = [f"{st.name}: {st.error}" for st in states if st.error]
        if errors:
            out["daq_error"] = "; ".join(errors)
        try:
            with request.app.state.Session() as session:
                session.execute(select(1))
                names = {b.id: b.name for b in crud.list_breakers(session)}
                now, timeout = utcnow(), timedelta(seconds=settings.daq_timeout_s)
                for d in crud.daq_statuses(session):
                    fresh = d.last_seen is not None and now - d.last_seen <= timeout
                    out["daq"].append({"breaker": names.get(d.breaker_id), "connected": bool(d.connected and fresh),
                                       "last_seen": d.last_seen.isoformat().replace("+00:00", "Z")
                                       if d.last_seen else None,
                                       "frames_dropped": d.frames_dropped, "crc_errors": d.crc_errors,
                                       "captures": d.captures})
        except (OperationalError, DBAPIError):
            out["status"], out["database"] = "degraded", "unavailable"
        if any(st.down for st in states) or (daq.enabled and not states):
            out["status"] = "degraded"
        return out

    @app.get("/metrics", tags=["service"], dependencies=[Depends(require("reader"))],
             response_class=Response, responses={200: {"content": {"text/plain": {}}}})
    def metrics(request: Request):
        """Prometheus metrics (reader key needed)."""
        body, ctype = render(request.app.state.metrics_registry)
        return Response(body, media_type=ctype)

    return app
