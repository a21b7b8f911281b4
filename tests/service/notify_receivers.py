"""Real receivers for the notification tests, on the loopback: an HTTP webhook receiver that
checks nothing and records everything (the tests verify), and an SMTP server (aiosmtpd) that
requires STARTTLS and a login, with a self-signed certificate made by the openssl command."""

from __future__ import annotations

import json
import shutil
import ssl
import subprocess
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from tests.live_server import free_port


class WebhookReceiver:
    """``start()`` listens on ``port`` (the same port again after ``stop()``); ``requests`` are
    ``(headers, body bytes)`` in arrival order. ``status`` is what it answers."""

    def __init__(self, port: int | None = None, status: int = 204):
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}/hook"
        self.status = status
        self.requests: list[tuple[dict, bytes]] = []
        self.lock = threading.Lock()
        self.server = self.thread = None

    def start(self) -> "WebhookReceiver":
        receiver = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):
                data = self.rfile.read(int(self.headers.get("Content-Length", 0)))
                with receiver.lock:
                    receiver.requests.append(({k.lower(): v for k, v in self.headers.items()}, data))
                self.send_response(receiver.status)
                self.send_header("Content-Length", "0")
                self.end_headers()

            def log_message(self, *args):
                pass

        ThreadingHTTPServer.allow_reuse_address = True
        self.server = ThreadingHTTPServer(("127.0.0.1", self.port), Handler)
        self.thread = threading.Thread(target=self.server.serve_forever, name="test-webhook", daemon=True)
        self.thread.start()
        return self

    def stop(self) -> None:
        if self.server is not None:
            self.server.shutdown()
            self.server.server_close()
            self.thread.join(timeout=10)
            self.server = self.thread = None

    def messages(self) -> list[dict]:
        with self.lock:
            return [json.loads(b) for _, b in self.requests]

    def events(self) -> list[dict]:
        return [e for m in self.messages() for e in m["events"]]


def self_signed_cert(directory: Path) -> tuple[Path, Path]:
    """(cert, key) for 127.0.0.1, made by the openssl command (Debian's openssl package)."""
    if shutil.which("openssl") is None:
        pytest.skip("SMTP lane off: the openssl command (to make the test server's certificate) is not installed")
    cert, key = directory / "smtp-cert.pem", directory / "smtp-key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out", str(cert),
                    "-days", "2", "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1"],
                   check=True, capture_output=True)
    return cert, key


class SmtpReceiver:
    """aiosmtpd on the loopback: STARTTLS required, then AUTH (``user``/``password``) required."""

    user, password = "hvcb-notifier", "a-real-smtp-password-42"

    def __init__(self, directory: Path):
        self.cert, self.key = self_signed_cert(directory)
        self.port = free_port()
        self.messages: list = []
        self.logins: list[str] = []
        self.controller = None

    def start(self) -> "SmtpReceiver":
        from aiosmtpd.controller import Controller
        from aiosmtpd.smtp import AuthResult, LoginPassword

        receiver = self

        class Handler:
            async def handle_DATA(self, server, session, envelope):
                import email

                receiver.messages.append(email.message_from_bytes(envelope.original_content or envelope.content))
                return "250 OK"

        def authenticator(server, session, envelope, mechanism, auth_data):
            ok = (isinstance(auth_data, LoginPassword) and auth_data.login.decode() == receiver.user
                  and auth_data.password.decode() == receiver.password and session.ssl is not None)
            if ok:
                receiver.logins.append(auth_data.login.decode())
            return AuthResult(success=ok)

        ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
        ctx.load_cert_chain(str(self.cert), str(self.key))
        self.controller = Controller(Handler(), hostname="127.0.0.1", port=self.port, tls_context=ctx,
                                     require_starttls=True, auth_required=True, auth_require_tls=True,
                                     authenticator=authenticator)
        self.controller.start()
        return self

    def stop(self) -> None:
        if self.controller is not None:
            self.controller.stop()
            self.controller = None

    def route(self, name: str = "mail", **kw) -> dict:
        return {"name": name, "kind": "email", "smtp_host": "127.0.0.1", "smtp_port": self.port, "starttls": True,
                "ca_file": str(self.cert), "username": self.user, "password": self.password,
                "sender": "hvcb@substation.example", "to": ["asset.engineer@utility.example"], **kw}


def poll(fn, timeout: float, what: str, every: float = 0.05):
    deadline = time.monotonic() + timeout
    last = None
    while time.monotonic() < deadline:
        last = fn()
        if last:
            return last
        time.sleep(every)
    raise AssertionError(f"{what} not seen within {timeout} s (last: {last!r})")
