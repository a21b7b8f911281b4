"""D15: signing in again while carrying a valid session ends that session."""

from __future__ import annotations


import pytest

from service.web import auth
from tests.web_forms import sign_in, signin_csrf

from .conftest import sqlite_url


@pytest.fixture
def db_url(tmp_path):
    """SQLite only: this finding does not depend on the database."""
    return sqlite_url(tmp_path)


def test_a_second_sign_in_ends_the_session_the_browser_carried(env):
    sign_in(env.client, env.keys["reader"])
    first = env.client.cookies.get(auth.COOKIE)
    assert env.client.get("/", follow_redirects=False).status_code == 200

    sign_in(env.client, env.keys["operator"])  # the browser sends its first cookie along
    second = env.client.cookies.get(auth.COOKIE)
    assert second and second != first
    assert env.client.get("/upload", follow_redirects=False).status_code == 200  # the new session works

    env.client.cookies.set(auth.COOKIE, first)  # someone replaying the old cookie
    r = env.client.get("/", follow_redirects=False)
    assert r.status_code == 401 and "ended" in r.text


def test_a_failed_sign_in_leaves_the_current_session_alone(env):
    sign_in(env.client, env.keys["reader"])
    r = env.client.post("/signin", data={"api_key": "hvcb_wrong", "csrf_token": signin_csrf(env.client), "next": "/"},
                        follow_redirects=False)
    assert r.status_code == 401
    assert env.client.get("/", follow_redirects=False).status_code == 200
