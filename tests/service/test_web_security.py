"""The web page's sign-in, session cookie, CSRF protection, roles and escaping (no browser needed)."""

from __future__ import annotations

import time
from datetime import timedelta

import pytest
from itsdangerous import TimestampSigner, URLSafeTimedSerializer
from sqlalchemy import select, update

from conftest import BREAKER_FILE
from tests.web_forms import page_csrf, sign_in, signin_csrf  # noqa: F401 (sign_in: other modules import it here)
from service.storage import crud
from service.storage.models import AlarmRow, BreakerRow, WebSessionRow, utcnow

EVIL = '<script>alert("x")</script>'
EVIL_ESCAPED = "&lt;script&gt;alert(&#34;x&#34;)&lt;/script&gt;"


def test_cookie_is_signed_httponly_strict_and_the_key_never_leaves_the_form(env):
    r = sign_in(env.client, env.keys["reader"])
    cookie = r.headers["set-cookie"]
    assert "hvcb_session=" in cookie and "HttpOnly" in cookie and "samesite=strict" in cookie.lower()
    assert "Secure" not in cookie  # plain HTTP here; HTTPS adds it (secure_cookie = "auto")
    assert env.keys["reader"] not in cookie and env.keys["reader"] not in r.headers["location"]
    page = env.client.get("/")
    assert page.status_code == 200 and env.keys["reader"] not in page.text
    assert "Content-Security-Policy" in page.headers and "default-src 'self'" in page.headers["Content-Security-Policy"]
    with env.Session() as s:  # only the token's hash is stored
        row = s.scalars(select(WebSessionRow)).one()
        token = env.app.state.web_signer.unsign(env.client.cookies["hvcb_session"])
        assert row.token_hash != token and len(row.token_hash) == 64


def test_secure_flag_behind_https(tmp_path, db_url):
    from fastapi.testclient import TestClient

    from conftest import make_settings
    from service.api.app import create_app

    shown = []
    app = create_app(make_settings(tmp_path, db_url), on_key=shown.append)
    with TestClient(app, base_url="https://hvcb.example") as client:
        r = sign_in(client, shown[0])
        assert "Secure" in r.headers["set-cookie"]


def test_no_cookie_redirects_to_sign_in_and_data_is_401(env):
    r = env.client.get("/breakers/1", follow_redirects=False)
    assert r.status_code == 303 and r.headers["location"].startswith("/signin")
    assert env.client.get("/ui/marker").status_code == 401
    assert env.client.get("/ui/breakers/1/trends.json").status_code == 401
    # an API key header does not open pages: the page needs a session
    assert env.client.get("/ui/marker", headers=env.h()).status_code == 401
    # ... and the JSON API keeps working with X-API-Key exactly as before
    assert env.client.get("/api/v1/breakers", headers=env.h("reader")).status_code == 200
    assert env.client.get("/api/v1/breakers").status_code == 401


def test_wrong_key_and_wrong_role_cannot_sign_in(env):
    for key in ("hvcb_not-a-key", ""):
        r = env.client.post("/signin", data={"api_key": key, "csrf_token": signin_csrf(env.client)},
                            follow_redirects=False)
        assert r.status_code == 401 and "hvcb_session" not in r.headers.get("set-cookie", "")


@pytest.mark.parametrize("forgery", ["garbage", "tampered", "other-secret"])
def test_forged_cookie_is_401(env, forgery):
    sign_in(env.client, env.keys["admin"])
    good = env.client.cookies["hvcb_session"]
    cookie = {"garbage": "not-a-session",
              "tampered": good[:-3] + ("AAA" if not good.endswith("AAA") else "BBB"),
              "other-secret": URLSafeTimedSerializer(b"x" * 48, salt="hvcb-web-session").dumps(
                  env.app.state.web_signer.unsign(good))}[forgery]
    env.client.cookies.clear()
    env.client.cookies.set("hvcb_session", cookie)
    for path in ("/", "/alarms", "/ui/marker"):
        r = env.client.get(path, follow_redirects=False)
        assert r.status_code == 401, (path, r.status_code)
    assert "Sign in" in env.client.get("/", follow_redirects=False).text


def test_expired_cookie_is_401(env):
    signer = env.app.state.web_signer
    sign_in(env.client, env.keys["admin"])
    token = signer.unsign(env.client.cookies["hvcb_session"])

    class OldSigner(TimestampSigner):  # the same secret, signed a lifetime ago
        def get_timestamp(self):
            return int(time.time() - signer.lifetime_s - 60)

    old = URLSafeTimedSerializer(signer._secret, salt="hvcb-web-session", signer=OldSigner).dumps(token)
    env.client.cookies.clear()
    env.client.cookies.set("hvcb_session", old)
    assert env.client.get("/", follow_redirects=False).status_code == 401
    # a fresh signature does not help once the stored session has expired
    env.client.cookies.clear()
    env.client.cookies.set("hvcb_session", signer.sign(token))
    assert env.client.get("/").status_code == 200
    with env.Session() as s, s.begin():
        s.execute(update(WebSessionRow).values(expires_at=utcnow() - timedelta(seconds=1)))
    assert env.client.get("/", follow_redirects=False).status_code == 401


def test_sign_out_and_key_revocation_end_the_session(env):
    sign_in(env.client, env.keys["reader"])
    cookie = env.client.cookies["hvcb_session"]
    r = env.client.post("/signout", data={"csrf_token": page_csrf(env.client)}, follow_redirects=False)
    assert r.status_code == 303
    env.client.cookies.set("hvcb_session", cookie)  # a copy kept by an attacker
    assert env.client.get("/", follow_redirects=False).status_code == 401

    env.client.cookies.clear()
    sign_in(env.client, env.keys["operator"])
    assert env.client.get("/").status_code == 200
    with env.Session() as s:
        op_key = next(k for k in crud.list_api_keys(s) if k.role == "operator")
    assert env.client.delete(f"/api/v1/keys/{op_key.id}", headers=env.h()).status_code == 200
    assert env.client.get("/", follow_redirects=False).status_code == 401


def test_post_without_or_with_a_wrong_csrf_token_is_refused(env):
    sign_in(env.client, env.keys["admin"])
    form = {"reason": "maintenance", "confirm": "yes"}
    for extra in ({}, {"csrf_token": "0" * 64}):
        r = env.client.post("/breakers/1/baseline/reset", data={**form, **extra}, follow_redirects=False)
        assert r.status_code == 403
    token = page_csrf(env.client, "/breakers/1")
    for origin in ("https://evil.example", "null"):
        r = env.client.post("/breakers/1/baseline/reset", data={**form, "csrf_token": token},
                            headers={"Origin": origin}, follow_redirects=False)
        assert r.status_code == 403
    with env.Session() as s:
        assert s.get(BreakerRow, 1).baseline_reset_at is None  # nothing changed
    # the sign-in form is protected too
    r = env.client.post("/signin", data={"api_key": env.keys["admin"]}, follow_redirects=False)
    assert r.status_code == 403
    # with the token (and no confirmation) the reset is still refused; with both it happens
    r = env.client.post("/breakers/1/baseline/reset", data={"reason": "x", "csrf_token": token},
                        follow_redirects=False)
    assert r.status_code == 400
    r = env.client.post("/breakers/1/baseline/reset", data={**form, "csrf_token": token}, follow_redirects=False)
    assert r.status_code == 303
    with env.Session() as s:
        assert s.get(BreakerRow, 1).baseline_reset_at is not None


def _raised_alarm(env, breaker_id: int, message: str, comment: str | None = None) -> int:
    with env.Session() as s, s.begin():
        alarm = AlarmRow(breaker_id=breaker_id, parameter="DO", level="alarm", state="raised", message=message,
                         evidence={"baseline": {"mean": 39.5, "sd": 0.3, "n": 20},
                                   "drift_direction": message, "watched_direction": "falling",
                                   "statistic": 5.0, "thresholds": {"warning": 3.0, "alarm": 4.5}},
                         ack_comment=comment)
        s.add(alarm)
        s.flush()
        return alarm.id


def test_roles_enforced_server_side(env):
    alarm_id = _raised_alarm(env, 1, "DO falling")
    sign_in(env.client, env.keys["reader"])
    page = env.client.get("/alarms")
    assert f'data-alarm-id="{alarm_id}"' in page.text
    assert "data-ack" not in page.text and "Reset baseline" not in page.text
    token = page_csrf(env.client, "/alarms")
    assert env.client.post(f"/alarms/{alarm_id}/ack", data={"csrf_token": token},
                           follow_redirects=False).status_code == 403
    assert env.client.get("/upload").status_code == 403
    assert env.client.post("/breakers/1/baseline/reset", data={"reason": "x", "confirm": "yes", "csrf_token": token},
                           follow_redirects=False).status_code == 403

    env.client.cookies.clear()
    sign_in(env.client, env.keys["operator"])
    page = env.client.get("/alarms")
    assert "data-ack" in page.text and "Reset baseline" not in page.text
    token = page_csrf(env.client, "/alarms")
    r = env.client.post(f"/alarms/{alarm_id}/ack", data={"csrf_token": token, "comment": "seen"},
                        follow_redirects=False)
    assert r.status_code == 303
    with env.Session() as s:
        a = s.get(AlarmRow, alarm_id)
        assert a.state == "acknowledged" and a.acknowledged_by == "test-operator" and a.ack_comment == "seen"
    assert env.client.post("/breakers/1/baseline/reset", data={"reason": "x", "confirm": "yes", "csrf_token": token},
                           follow_redirects=False).status_code == 403

    env.client.cookies.clear()
    sign_in(env.client, env.keys["admin"])
    assert "Reset baseline" in env.client.get("/alarms").text


def test_every_page_escapes_stored_text(env, breaker):
    """A breaker name, key name, alarm message, evidence, acknowledgement comment, operation flags
    and a fit's failure reason holding markup are shown as text on every page."""
    from service.storage.spool import Spool

    text = BREAKER_FILE.read_text().replace('name = "reference-252kV"', f"name = '{EVIL}'")
    cam = (BREAKER_FILE.parent / "reference-252kV.cam.csv").read_text()
    r = env.client.post("/api/v1/breakers", json={"breaker_file": text, "cam_table": cam, "tag": "Q9"},
                        headers=env.h())
    assert r.status_code == 422 and "name" in r.json()["detail"], r.text  # markup is not a breaker name
    with env.Session() as s, s.begin():  # a name stored before names were checked is still shown as text
        bid = crud.upsert_breaker(s, name=EVIL, tag="Q9", breaker_file=text.replace(EVIL, "evil-bay"),
                                  cam_file_name="reference-252kV.cam.csv", cam_table=cam).id
    with env.Session() as s, s.begin():
        _, key = crud.create_api_key(s, name=EVIL, role="admin")
        op, _ = crud.create_operation(s, capture_key=Spool.new_key(), breaker_id=bid, kind="open",
                                      occurred_at=utcnow(), source="upload", capture_path="/nonexistent/x.cfg",
                                      capture_sha256="0" * 64, flags=[EVIL], sample_rate=128000.0, n_samples=10)
        crud.store_fit_failure(s, operation_id=op.id, reason=f"capture unusable: {EVIL}")
        op_id = op.id
    alarm_id = _raised_alarm(env, bid, EVIL, comment=EVIL)
    with env.Session() as s, s.begin():
        s.execute(update(AlarmRow).where(AlarmRow.id == alarm_id).values(state="acknowledged",
                                                                           acknowledged_by=EVIL,
                                                                           acknowledged_at=utcnow()))
    sign_in(env.client, key)
    pages = ["/", f"/breakers/{bid}", "/alarms?state=all", "/alarms", f"/operations/{op_id}", "/upload"]
    for path in pages:
        r = env.client.get(path)
        assert r.status_code == 200, path
        assert "<script>alert" not in r.text, path
        assert EVIL_ESCAPED in r.text, path  # the text itself is shown
    assert "capture unusable: " + EVIL_ESCAPED in env.client.get(f"/operations/{op_id}").text
    # error pages too: a stored name in a redirect target is never reflected unescaped
    r = env.client.get(f"/breakers/{bid}?page=abc")
    assert "<script>" not in r.text
    # the chart data is JSON, never HTML
    r = env.client.get(f"/ui/breakers/{bid}/trends.json")
    assert r.headers["content-type"].startswith("application/json")
    # the capture file is gone: its data answers 410 in words, the page still renders
    r = env.client.get(f"/ui/operations/{op_id}/curves.json")
    assert r.status_code == 410 and "not readable" in r.json()["detail"]


def test_open_redirect_refused(env):
    r = env.client.post("/signin", data={"api_key": env.keys["reader"], "csrf_token": signin_csrf(env.client),
                                         "next": "//evil.example/x"}, follow_redirects=False)
    assert r.status_code == 303 and r.headers["location"] == "/"
