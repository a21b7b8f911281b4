"""D4: an upload is authorised from its headers and its size refused before its body is read."""

from __future__ import annotations

import socket

import httpx

ANNOUNCED = 200 * 1024 * 1024  # 200 MB announced, never sent


def _post_headers(live, path: str, headers: dict, length: int | None) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", live.port), timeout=20)
    lines = [f"POST {path} HTTP/1.1", "Host: 127.0.0.1", "Content-Type: multipart/form-data; boundary=xyz"]
    lines += [f"{k}: {v}" for k, v in headers.items()]
    lines.append(f"Content-Length: {length}" if length is not None else "Transfer-Encoding: chunked")
    sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
    return sock


def _status(sock: socket.socket) -> int:
    head = b""
    while b"\r\n" not in head:
        chunk = sock.recv(4096)
        assert chunk, "the server closed the connection without an answer"
        head += chunk
    return int(head.split(b" ", 2)[1])


def test_unauthenticated_200_mb_upload_is_answered_before_any_body_byte(live_server):
    live = live_server()
    for headers in ({}, {"X-API-Key": "hvcb_wrong"}):
        sock = _post_headers(live, "/api/v1/breakers/1/captures", headers, ANNOUNCED)
        try:
            assert _status(sock) == 401  # not one byte of the 200 MB was sent
        finally:
            sock.close()
    sock = _post_headers(live, "/upload", {}, ANNOUNCED)  # the web page's upload, no session cookie
    try:
        assert _status(sock) == 401
    finally:
        sock.close()


def test_reader_and_agent_roles_are_checked_before_the_body(live_server):
    live = live_server()
    sock = _post_headers(live, "/api/v1/breakers/1/captures", live.h("reader"), ANNOUNCED)
    try:
        assert _status(sock) == 403
    finally:
        sock.close()


def test_declared_length_above_the_limit_is_413_at_once_even_with_a_key(live_server):
    live = live_server()
    sock = _post_headers(live, "/api/v1/breakers/1/captures", live.h("operator"), ANNOUNCED)
    try:
        assert _status(sock) == 413
    finally:
        sock.close()


def test_chunked_body_is_counted_and_cut_at_the_limit(live_server):
    live = live_server(max_upload_bytes=64 * 1024)
    sent = 0

    def body():
        nonlocal sent
        yield b'--xyz\r\nContent-Disposition: form-data; name="files"; filename="a.cfg"\r\n\r\n'
        for _ in range(64):  # 4 MB offered, 64 kB allowed
            sent += 65536
            yield b"x" * 65536

    try:
        r = httpx.post(f"{live.base}/api/v1/breakers/1/captures", content=body(), timeout=30,
                       headers={**live.h("operator"), "Content-Type": "multipart/form-data; boundary=xyz"})
        status, detail = r.status_code, r.json()["detail"]
    except httpx.HTTPError:  # the server may close while we still send: then it must have cut us short
        status, detail = 413, "closed"
    assert status == 413 and ("limit" in detail or detail == "closed")
    assert sent < 4 * 1024 * 1024


def test_other_bodies_are_capped_too(live_server):
    live = live_server(server={"max_request_bytes": 4096})
    r = httpx.post(f"{live.base}/api/v1/keys", headers=live.h(), timeout=10,
                   content=b'{"name": "' + b"x" * 10_000 + b'", "role": "reader"}')
    assert r.status_code == 413
