"""D13: a client that trickles its headers, or stalls in its body, loses its connection."""

from __future__ import annotations

import socket
import time


def _closed_or_answer(sock: socket.socket, limit_s: float) -> bytes:
    """What the server sends before closing (b"" when it just closes); fails if it keeps the
    connection open past ``limit_s`` (a safety bound; the server's own limit is far below it)."""
    sock.settimeout(limit_s)
    out = b""
    while True:
        try:
            chunk = sock.recv(4096)
        except TimeoutError:
            raise AssertionError("the server kept a stalled connection open") from None
        except ConnectionResetError:
            return out
        if not chunk:
            return out
        out += chunk


def test_trickled_headers_are_cut_off(live_server):
    live = live_server(server={"header_timeout_s": 0.5})
    sock = socket.create_connection(("127.0.0.1", live.port))
    try:
        sock.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Slow: ")
        assert _closed_or_answer(sock, 30) == b""  # closed without a request ever being served
    finally:
        sock.close()


def test_kept_alive_connection_gets_the_header_limit_again(live_server):
    live = live_server(server={"header_timeout_s": 0.5, "keepalive_s": 60})
    sock = socket.create_connection(("127.0.0.1", live.port))
    try:
        sock.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        first = b""
        while b'"status"' not in first:  # the whole first answer (headers and body)
            chunk = sock.recv(4096)
            assert chunk, "closed before the first answer"
            first += chunk
        assert first.startswith(b"HTTP/1.1 200")
        sock.sendall(b"GET /healthz HTTP/1.1\r\nHo")  # the second request begins, then trickles
        assert _closed_or_answer(sock, 30) == b""
    finally:
        sock.close()


def test_stalled_body_is_408_and_closed(live_server):
    live = live_server(server={"body_idle_timeout_s": 0.5})
    sock = socket.create_connection(("127.0.0.1", live.port))
    try:
        sock.sendall(b"POST /api/v1/keys HTTP/1.1\r\nHost: x\r\nX-API-Key: " + live.keys["admin"].encode()
                     + b"\r\nContent-Type: application/json\r\nContent-Length: 100\r\n\r\n{\"name\": ")
        answer = _closed_or_answer(sock, 30)
        assert answer.startswith(b"HTTP/1.1 408"), answer[:200]
        assert b"connection: close" in answer.lower()
    finally:
        sock.close()


def test_a_prompt_client_is_not_affected(live_server):
    import httpx

    live = live_server(server={"header_timeout_s": 0.5, "body_idle_timeout_s": 0.5})
    with httpx.Client(base_url=live.base, timeout=30) as c:
        for _ in range(3):
            assert c.get("/healthz").status_code == 200
            time.sleep(0.2)
        r = c.post("/api/v1/keys", headers=live.h(), json={"name": "prompt", "role": "reader"})
        assert r.status_code == 201
