"""The request guard: an ASGI middleware in front of every route (docs/security.md).

- Admission: page and API reads run at most ``[server] max_active_requests`` at once; up to
  ``max_queued_requests`` more wait their turn (at most ``queue_timeout_s``); beyond that the
  answer is 503 with Retry-After, never a 500. ``/healthz``, the SCADA points, ``/metrics`` and
  static files bypass the queue: they never wait behind page loads.
- Uploads: the caller is authenticated and authorised from the headers *before* the body is
  read; a declared Content-Length above the limit is refused at once with 413; a chunked body
  is counted and cut at the limit. Every other body is capped at ``max_request_bytes``.
- Body read timeouts: a body that stalls ``body_idle_timeout_s`` between chunks, or takes
  longer than ``body_timeout_s`` in all, is answered 408 and the connection closed.
"""

from __future__ import annotations

import asyncio
import json
import logging
import re
import time

from starlette.exceptions import HTTPException

log = logging.getLogger("hvcb.guard")

API_UPLOAD = re.compile(r"^/api/v1/breakers/[^/]+/captures/?$")
WEB_UPLOAD = "/upload"
# never queued behind page loads: liveness, SCADA pollers, Prometheus, static assets
PRIORITY_PREFIXES = ("/healthz", "/api/v1/scada/", "/metrics", "/static/", "/favicon")
MULTIPART_SLACK = 64 * 1024  # multipart boundaries and part headers around the files' bytes


class BodyLimit(HTTPException):
    """Raised from ``receive`` when the body passes its limit or stalls."""


def _header(scope, name: bytes) -> str | None:
    for k, v in scope.get("headers", ()):
        if k == name:
            return v.decode("latin-1")
    return None


async def _answer(send, status: int, detail: str, *, headers: dict | None = None, close: bool = True) -> None:
    body = json.dumps({"detail": detail}).encode()
    hdrs = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
            (b"cache-control", b"no-store")]
    if close:  # the body was not read: the connection cannot carry another request
        hdrs.append((b"connection", b"close"))
    for k, v in (headers or {}).items():
        hdrs.append((k.lower().encode(), str(v).encode()))
    await send({"type": "http.response.start", "status": status, "headers": hdrs})
    await send({"type": "http.response.body", "body": body})


class Admission:
    """At most ``active`` requests inside, up to ``queued`` waiting, each at most ``timeout_s``."""

    def __init__(self, active: int, queued: int, timeout_s: float):
        self.active, self.queued, self.timeout_s = active, queued, timeout_s
        self.waiting = 0
        self.inside = 0
        self.shed = 0
        self._sem: asyncio.Semaphore | None = None

    def semaphore(self) -> asyncio.Semaphore:
        if self._sem is None:
            self._sem = asyncio.Semaphore(self.active)
        return self._sem

    async def enter(self) -> bool:
        sem = self.semaphore()
        if not sem.locked():  # a free slot: asyncio takes it without suspending
            await sem.acquire()
            self.inside += 1
            return True
        # Shed on the total in the system: a waiter that has just been handed a slot is still
        # counted as waiting until it resumes, so ``waiting`` alone runs high for a moment.
        if self.inside + self.waiting >= self.active + self.queued:
            self.shed += 1
            return False
        self.waiting += 1
        try:
            async with asyncio.timeout(self.timeout_s):  # unlike 3.11's wait_for, never loses a permit
                await sem.acquire()
        except TimeoutError:
            self.shed += 1
            return False
        finally:
            self.waiting -= 1
        self.inside += 1
        return True

    def leave(self) -> None:
        self.inside -= 1
        self.semaphore().release()


class RequestGuard:
    def __init__(self, app, settings, fastapi_app):
        self.app = app
        self.settings = settings
        self.fastapi_app = fastapi_app
        srv = settings.server
        self.admission = Admission(srv.max_active_requests, srv.max_queued_requests, srv.queue_timeout_s)
        fastapi_app.state.admission = self.admission

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        path, method = scope["path"], scope["method"]
        srv = self.settings.server
        upload = method == "POST" and (path == WEB_UPLOAD or API_UPLOAD.match(path) is not None)
        limit = self.settings.max_upload_bytes + MULTIPART_SLACK if upload else srv.max_request_bytes
        declared = _header(scope, b"content-length")
        if upload:
            refusal = await self._preauthorise(scope, path)
            if refusal is not None:
                status, detail, headers = refusal
                return await _answer(send, status, detail, headers=headers)
        if declared is not None and declared.strip().isdigit() and int(declared) > limit:
            return await _answer(send, 413, f"request body of {int(declared)} bytes is larger than the "
                                            f"{limit - (MULTIPART_SLACK if upload else 0)} byte limit")
        state = {"read": 0, "aborted": False, "started": time.monotonic(), "complete": False}

        async def guarded_receive():
            if state["complete"]:  # the body is in; later calls wait for a disconnect, untimed
                return await receive()
            try:
                message = await asyncio.wait_for(receive(), srv.body_idle_timeout_s)
            except TimeoutError:
                state["aborted"] = True
                raise BodyLimit(408, f"the request body stalled for {srv.body_idle_timeout_s:g} s") from None
            if message["type"] == "http.request":
                state["read"] += len(message.get("body", b""))
                if state["read"] > limit:
                    state["aborted"] = True
                    raise BodyLimit(413, f"request body larger than the "
                                         f"{limit - (MULTIPART_SLACK if upload else 0)} byte limit")
                state["complete"] = not message.get("more_body", False)
                if message.get("more_body") and time.monotonic() - state["started"] > srv.body_timeout_s:
                    state["aborted"] = True
                    raise BodyLimit(408, f"the request body took longer than {srv.body_timeout_s:g} s")
            return message

        async def guarded_send(message):
            if message["type"] == "http.response.start" and state["aborted"]:
                message = {**message, "headers": [*message.get("headers", []), (b"connection", b"close")]}
            await send(message)

        if path.startswith(PRIORITY_PREFIXES):
            return await self.app(scope, guarded_receive, guarded_send)
        if not await self.admission.enter():
            retry = max(1, int(srv.queue_timeout_s // 4))
            log.warning("shedding %s %s: %d requests active, %d waiting", method, path, self.admission.active,
                        self.admission.waiting)
            return await _answer(send, 503, "the service is busy: try again shortly",
                                 headers={"Retry-After": retry}, close=False)
        try:
            await self.app(scope, guarded_receive, guarded_send)
        finally:
            self.admission.leave()

    async def _preauthorise(self, scope, path: str):
        """(status, message) refusing the upload from its headers alone, or None to go on."""
        from starlette.requests import Request

        request = Request(scope)
        if path == WEB_UPLOAD:
            from fastapi.concurrency import run_in_threadpool

            from service.web import auth

            try:
                user = await run_in_threadpool(auth.current_user, request)
            except auth.WebAuthError as exc:
                return (401, exc.message, None)
            if not user.can("operator"):
                return (403, f"uploading needs the operator role; you are signed in as {user.role}", None)
            return None
        from .keys import authorise_key

        try:
            await authorise_key(request, request.headers.get("x-api-key"), "operator", also=("agent",))
        except HTTPException as exc:
            return (exc.status_code, exc.detail, {k: v for k, v in (exc.headers or {}).items()})
        return None
