"""D7: wrong keys and sign-ins are throttled per client address with exponential delay and a
logged warning; the real admin, from an address that is not throttled, always gets in."""

from __future__ import annotations

import logging

import pytest
from fastapi.testclient import TestClient

from service.api.throttle import AuthThrottle

from .conftest import sqlite_url
from tests.web_forms import signin_csrf


@pytest.fixture
def db_url(tmp_path):
    """SQLite only: this finding does not depend on the database."""
    return sqlite_url(tmp_path)


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


def test_delay_doubles_past_the_free_failures_and_is_capped(caplog):
    clock = Clock()
    th = AuthThrottle(free_failures=3, base_s=0.5, max_s=4.0, forget_s=600, clock=clock)
    with caplog.at_level(logging.WARNING, logger="hvcb.throttle"):
        delays = [th.failed("10.0.0.9", "API keys") for _ in range(8)]
    assert delays == [0, 0, 0, 0.5, 1.0, 2.0, 4.0, 4.0]
    assert "throttled" in caplog.text and "10.0.0.9" in caplog.text
    assert th.blocked_for("10.0.0.9") == pytest.approx(8.0)  # the answer held 4 s, then 4 s more
    assert th.blocked_for("10.0.0.10") == 0  # another address is untouched
    clock.t += 8.1
    assert th.blocked_for("10.0.0.9") == 0
    th.succeeded("10.0.0.9")
    assert th.failed("10.0.0.9", "API keys") == 0  # a success starts the address afresh
    clock.t += 601
    assert [th.failed("10.0.0.11", "x") for _ in range(3)] == [0, 0, 0]


@pytest.fixture
def throttled_env(tmp_path, db_url):
    from service.api.app import create_app
    from service.storage import crud

    from .conftest import make_settings

    settings = make_settings(tmp_path, db_url, server={"auth_free_failures": 2, "auth_delay_base_s": 5.0,
                                                       "auth_delay_max_s": 30.0})
    shown = []
    app = create_app(settings, on_key=shown.append)
    attacker = TestClient(app, client=("192.0.2.66", 40000))
    admin = TestClient(app, client=("192.0.2.1", 40001))
    with attacker, admin:
        with app.state.Session() as s, s.begin():
            reader = crud.create_api_key(s, name="reader", role="reader")[1]
        yield attacker, admin, {"admin": shown[0], "reader": reader}


def test_wrong_keys_from_one_address_are_throttled_and_the_admin_elsewhere_gets_in(throttled_env, caplog):
    attacker, admin, keys = throttled_env
    with caplog.at_level(logging.WARNING, logger="hvcb.throttle"):
        codes = [attacker.get("/api/v1/breakers", headers={"X-API-Key": f"hvcb_guess{i}"}).status_code
                 for i in range(4)]
    # two free; the third is held back 5 s before its 401, and the address may not try for 5 s more
    assert codes == [401, 401, 401, 429]
    r = attacker.get("/api/v1/breakers", headers={"X-API-Key": "hvcb_guess_again"})
    assert r.status_code == 429 and int(r.headers["Retry-After"]) >= 1
    assert "192.0.2.66" in caplog.text
    # the real admin, on its own address, is not slowed or refused
    assert admin.get("/api/v1/breakers", headers={"X-API-Key": keys["admin"]}).status_code == 200
    # the web sign-in shares the throttle: a wrong key from the attacker's address is refused there too
    r = attacker.post("/signin", data={"api_key": "hvcb_guess_web", "csrf_token": signin_csrf(attacker),
                                       "next": "/"}, follow_redirects=False)
    assert r.status_code == 429
    # ... but a right key from that same address (the real admin behind the attacker's NAT) gets in,
    # on the API and the page, and does not unblock the address for the wrong ones
    assert attacker.get("/api/v1/breakers", headers={"X-API-Key": keys["admin"]}).status_code == 200
    r = attacker.post("/signin", data={"api_key": keys["reader"], "csrf_token": signin_csrf(attacker), "next": "/"},
                      follow_redirects=False)
    assert r.status_code == 303
    assert attacker.get("/api/v1/breakers", headers={"X-API-Key": "hvcb_guess_3"}).status_code == 429
    r = admin.post("/signin", data={"api_key": keys["reader"], "csrf_token": signin_csrf(admin), "next": "/"},
                   follow_redirects=False)
    assert r.status_code == 303


def test_wrong_sign_ins_count_towards_the_throttle(throttled_env):
    attacker, _, keys = throttled_env
    codes = []
    for i in range(5):
        r = attacker.post("/signin", data={"api_key": f"hvcb_guess{i}", "csrf_token": signin_csrf(attacker),
                                           "next": "/"}, follow_redirects=False)
        codes.append(r.status_code)
    assert codes == [401, 401, 401, 429, 429]
