"""D1: reads cannot starve the service. Page and API reads queue behind a bounded number of
active ones; beyond the queue they get 503 with Retry-After, never 500; /healthz and the SCADA
points never wait behind them; the database pool is sized from the thread count."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import httpx

from tests.web_forms import signin_csrf


def _holding_route(app, entered: threading.Semaphore, release: threading.Event):
    """A test-only read that holds its admission slot (and a thread) until released."""

    @app.get("/api/v1/test-hold")
    def hold():
        entered.release()
        release.wait(60)
        return {"ok": True}


def test_full_queue_sheds_with_503_and_retry_after_while_healthz_and_scada_answer(live_server):
    entered, release = threading.Semaphore(0), threading.Event()
    live = live_server(routes=lambda app: _holding_route(app, entered, release),
                       server={"threads": 8, "max_active_requests": 2, "max_queued_requests": 3})
    with httpx.Client(base_url=live.base, timeout=60, headers=live.h("reader")) as warm:
        assert warm.get("/api/v1/scada/points").status_code == 200  # the key is checked and cached
    pool = ThreadPoolExecutor(5)
    held = [pool.submit(httpx.get, f"{live.base}/api/v1/test-hold", timeout=90) for _ in range(5)]
    try:
        for _ in range(2):
            assert entered.acquire(timeout=30)  # two active...
        admission = live.app.state.admission
        deadline = threading.Event()
        for _ in range(300):  # ...and three waiting
            if admission.waiting == 3:
                break
            deadline.wait(0.05)
        assert admission.inside == 2 and admission.waiting == 3
        with httpx.Client(base_url=live.base, timeout=30) as c:
            shed = c.get("/api/v1/breakers", headers=live.h("reader"))
            assert shed.status_code == 503 and int(shed.headers["Retry-After"]) >= 1
            assert c.get("/healthz").status_code == 200
            assert c.get("/healthz", headers=live.h("reader")).json()["database"] == "ok"
            assert c.get("/api/v1/scada/points", headers=live.h("reader")).status_code == 200
    finally:
        release.set()
        statuses = [f.result().status_code for f in held]
        pool.shutdown()
    assert statuses == [200] * 5  # the queued ones were served, not dropped


def test_pool_is_sized_from_the_threads(live_server):
    live = live_server(server={"threads": 24, "max_active_requests": 16})
    assert live.app.state.engine.pool.size() == 24 + 12
    assert live.app.state.engine.pool._max_overflow == 0


def test_64_concurrent_page_and_api_reads_give_no_5xx(live_server, breaker):
    """Ordinary load on either database: everything is served (queued if need be)."""
    from .conftest import synth

    live = live_server(server={"threads": 12, "max_active_requests": 6})
    monitor = live.app.state.monitor
    for seed in range(3):
        monitor.ingest(synth(breaker, "open", seed=seed), breaker_id=1, operation="open")
    web = httpx.Client(base_url=live.base, timeout=120)
    r = web.post("/signin", data={"api_key": live.keys["reader"], "csrf_token": signin_csrf(web), "next": "/"},
                 follow_redirects=False)
    assert r.status_code == 303
    cookies = dict(web.cookies)
    web.close()
    paths = [("page", "/"), ("page", "/breakers/1"), ("page", "/ui/breakers/1/trends.json"),
             ("api", "/api/v1/breakers/1/health"), ("api", "/api/v1/breakers/1/operations"),
             ("api", "/api/v1/breakers/1/parameters?name=DO&limit=20000"), ("api", "/api/v1/alarms")]

    def read(i):
        kind, path = paths[i % len(paths)]
        with httpx.Client(base_url=live.base, timeout=120, cookies=cookies if kind == "page" else None) as c:
            return c.get(path, headers=live.h("reader") if kind == "api" else None).status_code

    with ThreadPoolExecutor(64) as pool:
        codes = list(pool.map(read, range(128)))
    assert not [c for c in codes if c >= 500], codes
    assert set(codes) == {200}
