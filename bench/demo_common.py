"""The demo as a new user starts it (``hvcb demo`` in a fresh data folder), for the benches that
measure the service while the demo runs: start it, read its admin key, stop it."""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Demo:
    """``hvcb demo`` in a subprocess with its own data folder; ``url``, ``key`` once started."""

    def __init__(self, data_dir: str | None = None, env: dict | None = None):
        self._tmp = None if data_dir else tempfile.TemporaryDirectory(prefix="hvcb-demo-bench-")
        self.data_dir = data_dir or self._tmp.name
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.key = None
        self.lines: list[str] = []
        self.env = {**os.environ, "HVCB_DATA_DIR": self.data_dir, **(env or {})}

    def start(self, timeout: float = 90.0) -> "Demo":
        self.started_at = time.monotonic()
        self.proc = subprocess.Popen([sys.executable, "-m", "service.cli", "demo", "--port", str(self.port)],
                                     cwd=ROOT, env=self.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True)
        got = threading.Event()

        def read():
            want = False
            for line in self.proc.stdout:
                self.lines.append(line.rstrip())
                if want and self.key is None:
                    self.key = line.strip()
                    got.set()
                want = "sign in with this API key" in line
        threading.Thread(target=read, daemon=True).start()
        if not got.wait(timeout):
            self.stop()
            raise RuntimeError("the demo did not start:\n" + "\n".join(self.lines[-30:]))
        self.ready_s = time.monotonic() - self.started_at
        return self

    def database_messages(self) -> list[str]:
        return [ln for ln in self.lines if re.search(r"locked|unavailable|503", ln)]

    def stop(self) -> None:
        if getattr(self, "proc", None) and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        if self._tmp is not None:
            self._tmp.cleanup()
