"""Acceptance (issue 38): an alarm raised on the demo (emulated Modbus DAQ → trigger → COMTRADE →
fit jobs in the local process pool → drift detector) reaches a real SMTP server (STARTTLS, login)
and a real webhook receiver on the loopback, signed and verifiable; SQLite and PostgreSQL."""

from __future__ import annotations


from conftest import make_settings
from notify_receivers import SmtpReceiver, WebhookReceiver, poll
from service.api.demo import DemoDaq, DemoScript
from test_notifications import check_signed, notifications, webhook

# The demo's history compressed (as tests/service/test_demo.py): a baseline, then a fast leak.
SCRIPT = DemoScript(healthy_ops=22, leak_per_op=0.03, total_ops=34, close_every=8, interval_s=0.15, seed=3)


def test_an_alarm_raised_on_the_demo_reaches_email_and_webhook_signed(tmp_path, db_url, breaker):
    from fastapi.testclient import TestClient

    from service.api.app import create_app

    smtp = SmtpReceiver(tmp_path).start()
    hook = WebhookReceiver().start()
    daq = DemoDaq(breaker, SCRIPT)
    port = daq.start()
    try:
        settings = make_settings(tmp_path, db_url, executor="local", acquisition={
            "driver": "modbus", "modbus": {"host": "127.0.0.1", "port": port, "poll_interval_s": 0.05}},
            notifications=notifications(webhook(hook.url), smtp.route(), page_url="http://127.0.0.1:8000"))
        shown = []
        app = create_app(settings, on_key=shown.append)
        with TestClient(app) as client:
            def do_alarm():
                r = client.get("/api/v1/alarms", params={"state": "all"}, headers={"X-API-Key": shown[0]})
                return [a for a in r.json() if a["parameter"] == "DO"]

            (alarm,) = poll(do_alarm, 240, "the DO alarm", every=0.25)
            raised = poll(lambda: [e for e in hook.events() if e["kind"] == "raised"], 30, "the webhook")
            poll(lambda: smtp.messages, 30, "the e-mail")
    finally:
        daq.stop()
        smtp.stop()
        hook.stop()
    ev = raised[0]
    assert ev["alarm"]["id"] == alarm["id"] and ev["parameter"] == "DO"
    assert ev["breaker"]["name"] == "reference-252kV" and ev["breaker"]["tag"] == "Q1"
    assert "buffer damping (DO) falling" in ev["alarm"]["message"]
    assert ev["alarm"]["operation_id"] is not None
    check_signed(hook)  # HMAC over timestamp + body verifies; schema-valid; idempotency key
    mail = smtp.messages[0]
    assert "raised" in mail["Subject"] and "reference-252kV (Q1) DO" in mail["Subject"]
    text = mail.get_payload(decode=True).decode()
    assert ev["id"] in text and "http://127.0.0.1:8000/breakers/1" in text and "buffer damping (DO)" in text
    ids = mail["X-Hvcb-Events"].split(",")
    assert ids[0] == ev["id"]  # the alarm's first event is the first mail's first
    if len(ids) == 1:
        assert mail["Message-ID"] == f"<{ev['id']}@hvcb>"
    assert smtp.logins and all(login == SmtpReceiver.user for login in smtp.logins)
