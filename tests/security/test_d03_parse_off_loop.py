"""D3: an upload is parsed on a worker thread, a bounded number at once: the event loop, and
so /healthz, never waits for a parse."""

from __future__ import annotations

import threading

import httpx

from .conftest import comtrade_pair, synth


def test_healthz_answers_while_an_upload_is_being_parsed_and_parses_are_bounded(live_server, breaker, monkeypatch):
    import service.jobs.upload as routes  # parse_upload looks the parser up here at call time

    real = routes.capture_from_upload
    entered, release = threading.Semaphore(0), threading.Event()
    inside, most = [0], [0]
    lock = threading.Lock()

    def held_parse(*args, **kwargs):  # a parse that takes as long as the test wants
        with lock:
            inside[0] += 1
            most[0] = max(most[0], inside[0])
        entered.release()
        release.wait(60)
        try:
            return real(*args, **kwargs)
        finally:
            with lock:
                inside[0] -= 1

    monkeypatch.setattr(routes, "capture_from_upload", held_parse)
    live = live_server(server={"upload_parsers": 1})
    cfg, dat = comtrade_pair(synth(breaker, "open", seed=3))
    results = []

    def upload():
        r = httpx.post(f"{live.base}/api/v1/breakers/1/captures", headers=live.h("operator"), timeout=90,
                       files=[("files", ("a.cfg", cfg)), ("files", ("a.dat", dat))])
        results.append(r.status_code)

    senders = [threading.Thread(target=upload) for _ in range(2)]
    for t in senders:
        t.start()
    assert entered.acquire(timeout=30)  # the first parse is running (and held)
    with httpx.Client(base_url=live.base, timeout=30) as c:
        for _ in range(5):
            assert c.get("/healthz").status_code == 200  # the loop is free while a parse runs
        assert c.get("/api/v1/breakers", headers=live.h("reader")).status_code == 200
    assert not entered.acquire(timeout=0.5)  # the second upload waits for the one parse slot
    release.set()
    for t in senders:
        t.join()
    assert results == [202, 202] and most[0] == 1
