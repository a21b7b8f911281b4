"""The one live server of the tests: an app under uvicorn in a thread, on a loopback port.

Used by the browser tests (tests/web/weblive.py), the OpenAPI fuzzing (schemathesis) and the
fleet tests' central server (tests/service/fleet_helpers.py).
"""

from __future__ import annotations

import socket
import threading
import time


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class LiveServer:
    """``app`` served at ``url`` between ``start()`` (returns once uvicorn serves) and ``stop()``.

    A stopped server can be started again on the same port (a central server going away and
    coming back). Also a context manager.
    """

    def __init__(self, app, *, port: int | None = None, name: str = "hvcb-test-server",
                 log_level: str = "error", config=None):
        """``config(app, port) -> uvicorn.Config`` serves with other settings (hvcb's own
        protocol and limits, for the security tests); by default a plain loopback config."""
        self.app, self.name, self.log_level, self.config = app, name, log_level, config
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.server = self.thread = None

    def start(self, timeout_s: float = 60.0) -> "LiveServer":
        import uvicorn

        config = (self.config(self.app, self.port) if self.config is not None else
                  uvicorn.Config(self.app, host="127.0.0.1", port=self.port, log_level=self.log_level, lifespan="on"))
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, name=self.name, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + timeout_s
        while not self.server.started:
            if not self.thread.is_alive() or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError(f"the test server {self.name} did not start on port {self.port}")
            time.sleep(0.05)
        return self

    def stop(self, timeout_s: float = 30.0) -> None:
        if self.server is not None:
            self.server.should_exit = True
            self.thread.join(timeout=timeout_s)
            self.server = self.thread = None

    def __enter__(self) -> "LiveServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
