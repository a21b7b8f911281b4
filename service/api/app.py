"""The app factory. Nothing is built at import time: tests and commands pass their own settings."""

from __future__ import annotations

import logging
import os
import threading
import time
from contextlib import asynccontextmanager
from pathlib import Path

from typing import Annotated

from fastapi import Depends, FastAPI, Request, Security
from fastapi.responses import JSONResponse, Response
from sqlalchemy import select
from sqlalchemy.exc import DBAPIError, OperationalError, TimeoutError as PoolTimeout

from service.errors import in_words
from service.settings import Settings
from service.storage import crud
from service.storage.db import make_engine, session_factory
from service.storage.schema import NotMigrated, check_schema  # noqa: F401 (NotMigrated: callers catch it)

from .contract import operation_id
from .guard import RequestGuard
from .methods import AllowedMethods
from .keys import KeyCache, api_key_header, authorise_key, require
from .throttle import AuthThrottle
from .metrics import build_registry, render

log = logging.getLogger("hvcb.api")

HEALTH_REFRESH_S = 0.5   # /healthz without a key answers from a snapshot this fresh...
HEALTH_MAX_AGE_S = 5.0   # ...and asks the database itself when the snapshot is older than this


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
    private_data_dir(settings)
    fd = os.open(settings.key_file, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as fh:
        fh.write(key + "\n")
    os.chmod(settings.key_file, 0o600)
    return key


def private_data_dir(settings: Settings) -> None:
    """The data folder and its folders 0700 (keys, curves and the database are inside)."""
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    for d in (settings.data_dir, settings.capture_dir, settings.spool_dir):
        if d.is_dir():
            os.chmod(d, 0o700)


def create_app(settings: Settings, *, executor=None, start_monitor: bool = True, on_key=None) -> FastAPI:
    """Build the service. ``executor`` replaces the configured one (tests); ``on_key(key)`` is
    called with a newly generated admin key (the commands print it)."""
    from service.jobs.ingest import Monitor
    from service.workers import make_executor
    from service.workers.breaker_diagnoses import BreakerDiagnosisRunner
    from service.workers.diagnoses import DiagnosisRunner
    from service.workers.reports import ReportRunner

    from service.notifications.routes import from_section

    from .daq import ServiceDaqs

    # The sections their own packages read: refused here, at start, in words (loading the
    # settings checks neither, so a command that needs neither starts at once).
    notification_settings = from_section(settings.notifications)
    settings.drift_settings  # noqa: B018  (the [alarms] section checked, its thresholds designed once)

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        import anyio.to_thread

        old_umask = os.umask(0o077)  # data files 0600, folders 0700, whatever umask we were started with
        private_data_dir(settings)
        srv = settings.server
        anyio.to_thread.current_default_thread_limiter().total_tokens = srv.threads
        app.state.priority_limiter = anyio.CapacityLimiter(4)
        engine = make_engine(settings.sqlalchemy_url, pool_size=srv.pool_size, sqlite_timeout_s=srv.sqlite_busy_s)
        check_schema(engine)
        Session = session_factory(engine)
        # /healthz, SCADA points and key checks: their own connections, never behind page loads
        priority_engine = make_engine(settings.sqlalchemy_url, pool_size=4, sqlite_timeout_s=srv.sqlite_busy_s)
        app.state.PrioritySession = session_factory(priority_engine)
        key = bootstrap(settings, Session)
        if key and on_key:
            on_key(key)
        ex = executor or make_executor(settings, on_result=lambda r: app.state.metrics_local.observe(r))
        monitor = Monitor(settings, Session, ex)
        daq = ServiceDaqs(settings, Session, monitor)
        app.state.engine, app.state.Session, app.state.monitor, app.state.daq = engine, Session, monitor, daq
        app.state.diagnoses = DiagnosisRunner(settings.sqlalchemy_url)
        app.state.breaker_diagnoses = BreakerDiagnosisRunner(settings)
        app.state.reports = ReportRunner(settings)  # condition reports: drawn in a worker process
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
        from service.notifications.capture import install as capture_notifications
        from service.notifications.notifier import Notifier

        capture_notifications()  # alarm transitions write their events (also via crud in this process)
        app.state.notifier = Notifier(app.state.notification_settings, Session)  # [notifications] routes
        if start_monitor:
            app.state.notifier.start()
        app.state.iec61850 = None
        if settings.iec61850_port:
            from service.iec61850.server import Iec61850Server

            try:
                app.state.iec61850 = Iec61850Server(settings, Session)
                app.state.iec61850.start()
            except Exception:
                app.state.retention.stop()
                app.state.notifier.stop()
                if start_monitor:
                    daq.stop()
                    monitor.stop()
                raise
        health_stop = threading.Event()
        health_thread = threading.Thread(target=_health_loop, args=(app, health_stop), name="hvcb-health", daemon=True)
        health_thread.start()
        try:
            yield
        finally:
            health_stop.set()
            health_thread.join(timeout=10)
            app.state.notifier.stop()
            app.state.retention.stop()
            if app.state.iec61850 is not None:
                app.state.iec61850.stop()
            app.state.diagnoses.shutdown()
            app.state.breaker_diagnoses.shutdown()
            app.state.reports.shutdown()
            if start_monitor:
                daq.stop()
                monitor.stop()
            else:
                ex.shutdown(wait=False)
            engine.dispose()
            priority_engine.dispose()
            os.umask(old_umask)

    app = FastAPI(title="hvcb", version="1", lifespan=lifespan, docs_url=None, redoc_url=None,
                  generate_unique_id_function=operation_id,
                  description="Condition monitor for spring-operated HV circuit-breaker mechanisms. "
                              "Send an API key in X-API-Key. Times are UTC ISO-8601 with Z.")
    app.state.settings = settings
    app.state.notification_settings = notification_settings
    app.state.key_cache = KeyCache()
    app.state.auth_throttle = AuthThrottle.from_settings(settings.server)
    app.state.upload_slots = None  # an asyncio.Semaphore made on first upload (it needs the loop)
    app.state.metrics_registry, app.state.metrics_local = build_registry(app)

    from .routes import router
    from .routes_alarms import router as alarm_router

    app.include_router(alarm_router)  # first: its paths never overlap the main router's
    app.include_router(router)

    from .routes_diagnoses import router as diagnoses_router  # breaker-level diagnoses (issue 20)

    app.include_router(diagnoses_router)
    from .routes_prognosis import router as prognosis_router  # issue 31

    app.include_router(prognosis_router)
    from .routes_setting import router as setting_router  # issue 39: the spring setting

    app.include_router(setting_router)
    from .routes_maintenance import router as maintenance_router  # issue 50: the maintenance log

    app.include_router(maintenance_router)
    from .routes_reports import router as reports_router  # issue 38: condition report, CSV exports

    app.include_router(reports_router)

    from .routes_keys import router as keys_router

    app.include_router(keys_router)

    from service.web import mount_web  # the engineers' web page at /

    mount_web(app)

    from .docs import mount_docs

    mount_docs(app)

    from .contract import install as install_contract

    install_contract(app)  # after the web: its pages keep their own error handlers

    @app.exception_handler(OperationalError)
    @app.exception_handler(DBAPIError)
    async def _db_down(request: Request, exc: Exception):
        log.warning("database error on %s: %s", request.url.path, in_words(exc))
        return JSONResponse({"detail": "database unavailable; try again shortly"}, status_code=503,
                            headers={"Retry-After": "5"})

    @app.exception_handler(PoolTimeout)
    async def _pool_busy(request: Request, exc: Exception):
        log.warning("no database connection free for %s within the pool timeout", request.url.path)
        return JSONResponse({"detail": "the service is busy: try again shortly"}, status_code=503,
                            headers={"Retry-After": "5"})

    app.add_middleware(RequestGuard, settings=settings, fastapi_app=app)
    app.add_middleware(AllowedMethods, fastapi_app=app)  # outside the guard: OPTIONS never queues

    @app.get("/healthz", tags=["service"], openapi_extra={"security": [{}]})  # public; a key adds details
    async def healthz(request: Request, key: Annotated[str | None, Security(api_key_header)] = None):
        """Liveness. Without a key: only ``{"status": "ok"}`` or ``"degraded"`` (the database does
        not answer or a DAQ is down). With any reader key: the details below.

        ``daqs``: this service's DAQs (``[[acquisition]]``), each with its state (starting, running,
        retrying, finished, stopped), ``up``, ``down``, last error, restarts and counters;
        ``daq_connected``: true when every one is up, null when none is configured; ``daq`` lists
        every breaker's last reported DAQ status (also remote ones); ``clock_suspect``: captures
        per breaker dated more than ``clock_tolerance_s`` after their arrival since the start.
        Any DAQ down: ``degraded``. Served on its own threads and database connections: it
        never waits behind page loads.
        """
        import anyio.to_thread

        detailed = False
        if key:
            await authorise_key(request, key, "reader")
            detailed = True
        snap = getattr(request.app.state, "health", None)
        if not detailed and snap is not None and time.monotonic() - snap[0] <= HEALTH_MAX_AGE_S:
            out = snap[1]  # answered on the event loop: no thread, no database connection to wait for
        else:  # details are read fresh (as is the status when the snapshot thread is behind), on the
            # priority threads with their own connections
            out = await anyio.to_thread.run_sync(_health, request.app, limiter=request.app.state.priority_limiter)
        return out if detailed else {"status": out["status"]}

    def _health_loop(app, stop: threading.Event) -> None:
        """Refresh the /healthz snapshot every HEALTH_REFRESH_S on its own thread and connections."""
        while not stop.is_set():
            try:
                app.state.health = (time.monotonic(), _health(app))
            except Exception:  # the next round tries again; /healthz falls back to asking itself
                log.warning("health snapshot failed", exc_info=True)
            stop.wait(HEALTH_REFRESH_S)

    def _health(app) -> dict:
        from datetime import timedelta

        from service.storage.models import utcnow

        monitor, daq = app.state.monitor, app.state.daq
        states = daq.states() if daq.enabled else []
        drivers = daq.drivers
        out = {"status": "ok", "database": "ok", "spooled_captures": len(monitor.spool),
               "daq_connected": all(st.up for st in states) if daq.enabled and states else
               (False if daq.enabled else None),
               "daq_driver": drivers[0] if len(drivers) == 1 else ("none" if not drivers else "multi"),
               "daqs": [st.to_dict() for st in states], "daq": [],
               "clock_suspect": dict(getattr(monitor, "clock_suspect", {}))}
        errors = [f"{st.name}: {st.error}" for st in states if st.error]
        if errors:
            out["daq_error"] = "; ".join(errors)
        try:
            with app.state.PrioritySession() as session:
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
        except (OperationalError, DBAPIError, PoolTimeout):
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
