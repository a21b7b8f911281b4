"""Signing in through the web form, for tests that drive the pages over HTTP (no browser)."""

from __future__ import annotations

import re

CSRF = re.compile(r'name="csrf_token" value="([^"]+)"')


def page_csrf(client, path: str = "/") -> str:
    """The CSRF token of the form on ``path``."""
    r = client.get(path)
    assert r.status_code == 200, r.text
    return CSRF.search(r.text).group(1)


def signin_csrf(client) -> str:
    return page_csrf(client, "/signin")


def sign_in(client, key: str):
    r = client.post("/signin", data={"api_key": key, "csrf_token": signin_csrf(client), "next": "/"},
                    follow_redirects=False)
    assert r.status_code == 303, r.text
    return r
