"""The engineers' web page: server-rendered pages (Jinja2, a little plain JavaScript, vendored
uPlot), signed in with an API key, served by the API's own app. ``mount_web(app)`` adds it."""

from __future__ import annotations

import logging
import threading
from contextlib import asynccontextmanager
from urllib.parse import quote

from fastapi import FastAPI, HTTPException, Request
from fastapi.exception_handlers import request_validation_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, RedirectResponse
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException

from service.storage import crud

from .render import HERE, build_templates, page, security_headers

log = logging.getLogger("hvcb.web")


def _is_web(request: Request) -> bool:
    """A page or page-data request (not the JSON API, docs or metrics)."""
    p = request.url.path
    return not p.startswith(("/api/", "/docs", "/redoc", "/openapi.json", "/metrics", "/healthz"))


def _warm_at_start(app: FastAPI) -> None:
    """After the app's own start-up, fill the trend cache of every breaker in a background thread,
    so the first breaker page after a restart does not read a long history while the user waits."""
    inner = app.router.lifespan_context

    @asynccontextmanager
    async def lifespan(a):
        async with inner(a) as state:
            store, stop = a.state.web_trends, threading.Event()

            def warm():
                try:
                    with a.state.Session() as session:
                        ids = [b.id for b in crud.list_breakers(session)]
                    store.warm(a.state.Session, ids, a.state.settings, stop=stop)
                except Exception:  # a cold cache is only slower; the page builds it on demand
                    log.warning("trend cache warm-up failed", exc_info=True)
                finally:
                    store.warmed.set()

            thread = threading.Thread(target=warm, name="hvcb-web-warm", daemon=True)
            thread.start()
            try:
                yield state
            finally:
                stop.set()
                thread.join(timeout=30)

    app.router.lifespan_context = lifespan


def mount_web(app: FastAPI) -> None:
    from . import auth
    from .routes import router
    from .trends import TrendStore

    settings = app.state.settings
    app.state.web_signer = auth.SessionSigner(auth.load_secret(settings), settings.web.session_hours * 3600.0)
    app.state.web_templates = build_templates()
    app.state.web_trends = TrendStore()
    _warm_at_start(app)
    app.include_router(router)
    from .routes_diagnoses import router as diagnoses_router  # "Diagnose the last N operations"

    app.include_router(diagnoses_router)
    from .routes_alarms import router as alarm_router

    app.include_router(alarm_router)
    from .routes_prognosis import router as prognosis_router  # the breaker page's fan chart data

    app.include_router(prognosis_router)
    from .routes_setting import router as setting_router  # the operation page's commissioning button

    app.include_router(setting_router)
    from .routes_maintenance import router as maintenance_router  # the breaker page's maintenance log

    app.include_router(maintenance_router)
    from .routes_reports import router as reports_router  # the condition report and CSV exports

    app.include_router(reports_router)
    from .routes_vibration import router as vibration_router  # the operation page's latch time and fingerprint

    app.include_router(vibration_router)
    app.mount("/static", StaticFiles(directory=HERE / "static"), name="static")

    @app.exception_handler(auth.WebAuthError)
    async def _auth_error(request: Request, exc: auth.WebAuthError):
        status = {"missing": 401, "invalid": 401, "signin": 401, "forbidden": 403, "csrf": 403}[exc.kind]
        if request.url.path.startswith("/ui/") or request.method != "GET":
            resp = JSONResponse({"detail": exc.message}, status_code=status) if request.url.path.startswith("/ui/") \
                else page(request, "error.html", {"status": status, "message": exc.message}, status_code=status)
        elif exc.kind == "missing":
            return security_headers(RedirectResponse(f"/signin?next={quote(request.url.path)}", status_code=303))
        else:
            resp = page(request, "error.html", {"status": status, "message": exc.message}, status_code=status)
        if exc.kind == "invalid":
            resp.delete_cookie(auth.COOKIE, path="/")
        return security_headers(resp)

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError):
        if _is_web(request) and not request.url.path.startswith(("/ui/", "/static/")):
            what = "; ".join(f"{'.'.join(str(p) for p in e.get('loc', ())[1:]) or 'request'}: {e.get('msg', '')}"
                             for e in exc.errors())
            return page(request, "error.html", {"status": 422, "message": f"the form was not complete: {what}"},
                        status_code=422)
        return await request_validation_exception_handler(request, exc)

    default_http = app.exception_handlers.get(StarletteHTTPException)

    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException):
        if _is_web(request) and not request.url.path.startswith(("/ui/", "/static/")):
            return page(request, "error.html", {"status": exc.status_code, "message": exc.detail},
                        status_code=exc.status_code)
        if default_http is not None:
            return await default_http(request, exc)
        return JSONResponse({"detail": exc.detail}, status_code=exc.status_code, headers=exc.headers)


__all__ = ["mount_web", "HTTPException"]
