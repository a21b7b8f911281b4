"""The HTTP server's settings (uvicorn): timeouts for slow clients and the connection limit.

uvicorn closes idle kept-alive connections (``timeout_keep_alive``) but has no limit on how
long a client may take to send a request's headers: a client trickling one header byte at a
time holds its connection for ever. ``HeaderTimeoutH11Protocol`` adds that limit: a connection
whose request headers are not complete ``[server] header_timeout_s`` after it opened (or after
the first byte of a later request on a kept-alive connection) is closed; an idle kept-alive
connection is closed after ``keepalive_s`` by uvicorn itself. Body read timeouts are in the request guard
(service/api/guard.py). docs/security.md lists every limit.
"""

from __future__ import annotations

import asyncio

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol


def header_timeout_protocol(header_timeout_s: float):
    """An h11 protocol class that closes connections whose headers take longer than ``header_timeout_s``."""

    class HeaderTimeoutH11Protocol(H11Protocol):
        _header_timer: asyncio.TimerHandle | None = None

        def _arm(self) -> None:
            self._disarm()
            self._header_timer = self.loop.call_later(header_timeout_s, self._headers_too_slow)

        def _disarm(self) -> None:
            if self._header_timer is not None:
                self._header_timer.cancel()
                self._header_timer = None

        def _headers_too_slow(self) -> None:
            self._header_timer = None
            if self.conn.their_state is h11.IDLE and not self.transport.is_closing():
                self.transport.close()  # no request started in time: nothing to answer

        def connection_made(self, transport) -> None:
            super().connection_made(transport)
            self._arm()

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            if self.conn.their_state is not h11.IDLE:  # the request line and headers are in
                self._disarm()
            elif self._header_timer is None and not self.transport.is_closing():
                self._arm()  # a later request on a kept-alive connection has begun: same limit

        def connection_lost(self, exc) -> None:
            self._disarm()
            super().connection_lost(exc)

    return HeaderTimeoutH11Protocol


def uvicorn_config(app, settings, **extra):
    """The uvicorn.Config of ``hvcb serve`` and ``hvcb demo``."""
    import uvicorn

    srv = settings.server
    return uvicorn.Config(app, host=settings.host, port=settings.port, log_level="warning",
                          http=header_timeout_protocol(srv.header_timeout_s),
                          timeout_keep_alive=srv.keepalive_s, limit_concurrency=srv.max_connections,
                          h11_max_incomplete_event_size=64 * 1024, proxy_headers=True,
                          forwarded_allow_ips=srv.trusted_proxies, **extra)
