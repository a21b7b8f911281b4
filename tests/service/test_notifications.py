"""Notifications with real parts (issue 38): alarm transitions stored by the service's own code
paths and the API, delivered by the notifier running in the app to a real HTTP receiver and a
real SMTP server (aiosmtpd, STARTTLS and login required) on the loopback; SQLite and PostgreSQL."""

from __future__ import annotations

import time
from collections import Counter, defaultdict

import jsonschema
import pytest
from sqlalchemy import func, select

from conftest import make_settings, running_app
from notify_receivers import SmtpReceiver, WebhookReceiver, poll
from service.alarms import AlarmEvent
from service.notifications.rows import NotificationDeliveryRow, NotificationEventRow, NotificationRouteRow
from service.notifications.schema import SCHEMA
from service.notifications.signature import verify
from service.storage import crud
from service.storage.models import BreakerRow, utcnow

SECRET = "test-webhook-secret-0f3a9c1e7b"


def notifications(*routes, **kw) -> dict:
    """Fast pacing for tests: the same code, shorter intervals."""
    return {"routes": list(routes), "group_interval_s": 0.2, "poll_s": 0.05, "retry_min_s": 0.05,
            "retry_max_s": 0.4, "max_events_per_message": 50, **kw}


def webhook(url: str, name: str = "hook", **kw) -> dict:
    return {"name": name, "kind": "webhook", "url": url, "secret": SECRET, "timeout_s": 2.0, **kw}


def check_signed(receiver: WebhookReceiver) -> None:
    """Every request is signed with the route's secret, carries its message id as the
    idempotency key and validates against the documented schema."""
    import json

    assert receiver.requests
    for headers, body in receiver.requests:
        assert verify(SECRET, timestamp=headers["x-hvcb-timestamp"], signature=headers["x-hvcb-signature"],
                      body=body, now=time.time()), "signature does not verify"
        assert not verify("another-secret-of-enough-length", timestamp=headers["x-hvcb-timestamp"],
                          signature=headers["x-hvcb-signature"], body=body, now=time.time())
        message = json.loads(body)
        assert headers["idempotency-key"] == message["message_id"]
        jsonschema.validate(message, SCHEMA)


def store(Session, breaker_id: int, kind: str, *, parameter="DO", level="warning", episode=1):
    """One detector event stored the way the worker stores it (service.jobs.fit)."""
    from service.jobs.fit import apply_alarm_event

    ev = AlarmEvent(kind=kind, parameter=parameter, level=level, episode=episode, operation_id=None,
                    time=utcnow(), evidence={"drift_direction": "falling"}, reason="statistic back below 1.0")
    with Session() as s, s.begin():
        apply_alarm_event(s, breaker_id=breaker_id, event=ev)


def acknowledge(Session, breaker_id: int, parameter="DO", by="duty engineer"):
    with Session() as s, s.begin():
        alarm = crud.active_alarm(s, breaker_id=breaker_id, parameter=parameter)
        crud.acknowledge_alarm(s, alarm=alarm, by=by, comment="seen")


def more_breakers(Session, n: int) -> list[int]:
    with Session() as s, s.begin():
        first = s.scalar(select(BreakerRow).order_by(BreakerRow.id))
        ids = [first.id]
        for i in range(n):
            row = crud.upsert_breaker(s, name=f"bay{i + 2}", tag=f"Q{i + 2}", breaker_file=first.breaker_file,
                                      cam_file_name=first.cam_file_name, cam_table=first.cam_table)
            ids.append(row.id)
    return ids


def routed_events(Session) -> list[int]:
    with Session() as s:
        return list(s.scalars(select(NotificationEventRow.id).where(NotificationEventRow.silenced.is_(None))
                              .order_by(NotificationEventRow.id)))


def backlog(Session, route="hook") -> int:
    with Session() as s:
        return s.scalar(select(func.count()).select_from(NotificationDeliveryRow)
                        .where(NotificationDeliveryRow.route == route, NotificationDeliveryRow.status == "pending"))


def considered_all(Session, route="hook") -> bool:
    """The route has taken in every stored event and sent what it routes."""
    from service.notifications.outbox import unconsidered

    with Session() as s:
        return unconsidered(s, route) == 0 and backlog(Session, route) == 0


def route_state(Session, route="hook") -> NotificationRouteRow:
    with Session() as s:
        return s.get(NotificationRouteRow, route)


def test_receiver_down_for_the_first_200_events_then_up_gets_each_once_in_order(tmp_path, db_url):
    """The receiver is unreachable while 204 events of three breakers are stored; the service is
    restarted in between; then the receiver comes up: every event arrives exactly once, in order
    per breaker, grouped (one message per interval), each message signed."""
    receiver = WebhookReceiver()  # not listening yet: connections are refused
    settings = make_settings(tmp_path, db_url, notifications=notifications(webhook(receiver.url)))
    with running_app(settings) as (app, client, keys):
        Session = app.state.Session
        breakers = more_breakers(Session, 2)
        for cycle in range(17):  # 17 cycles x 3 breakers x 4 events = 204
            for b in breakers:
                store(Session, b, "raised", episode=cycle + 1)
                store(Session, b, "escalated", level="alarm", episode=cycle + 1)
                acknowledge(Session, b)
                store(Session, b, "cleared", level="alarm", episode=cycle + 1)
        events = routed_events(Session)
        assert len(events) == 204
        poll(lambda: backlog(Session) == 204 and route_state(Session).failures >= 2, 30,
             "every event taken in, and the notifier retrying the unreachable receiver")
        assert "not reached" in route_state(Session).last_error
        assert receiver.requests == []
    # the service restarted; the receiver is back
    receiver.start()
    try:
        from fastapi.testclient import TestClient

        from service.api.app import create_app

        app = create_app(settings)
        with TestClient(app):
            poll(lambda: backlog(app.state.Session) == 0, 60, "the backlog delivered")
        got = receiver.events()
    finally:
        receiver.stop()
    ids = [e["id"] for e in got]
    assert len(ids) == 204 and len(set(ids)) == 204, "an event missing or delivered twice"
    assert sorted(e["sequence"] for e in got) == events
    per_breaker = defaultdict(list)
    for e in got:
        per_breaker[e["breaker"]["id"]].append(e["sequence"])
    assert set(per_breaker) == set(breakers)
    for seqs in per_breaker.values():
        assert seqs == sorted(seqs), "a breaker's events out of order"
    kinds = Counter(e["kind"] for e in got)
    assert kinds == {"raised": 51, "escalated": 51, "acknowledged": 51, "cleared": 51}
    assert len(receiver.requests) < 204 / 10, "a storm was not grouped"
    assert max(len(m["events"]) for m in receiver.messages()) <= 50
    check_signed(receiver)


def test_a_shelved_alarm_sends_nothing_until_it_is_unshelved(tmp_path, db_url):
    receiver = WebhookReceiver().start()
    settings = make_settings(tmp_path, db_url, notifications=notifications(webhook(receiver.url)))
    try:
        with running_app(settings) as (app, client, keys):
            Session, op = app.state.Session, {"X-API-Key": keys["operator"]}

            store(Session, 1, "raised")
            poll(lambda: [e["kind"] for e in receiver.events()] == ["raised"], 20, "the raised alarm")
            alarm_id = receiver.events()[0]["alarm"]["id"]
            r = client.post(f"/api/v1/alarms/{alarm_id}/shelve", headers=op,
                            json={"minutes": 60.0, "reason": "known leak, buffer ordered"})
            assert r.status_code == 200, r.text
            poll(lambda: [e["kind"] for e in receiver.events()] == ["raised", "shelved"], 20, "the shelve notice")
            shelved = receiver.events()[1]
            assert shelved["by"] == "test-operator" and shelved["reason"] == "known leak, buffer ordered"
            assert shelved["alarm"]["shelved_until"]
            n = len(receiver.requests)
            # while shelved: an acknowledgement and a clear and a new alarm on the same parameter
            assert client.post(f"/api/v1/alarms/{alarm_id}/ack", headers=op, json={"comment": "ok"}).status_code == 200
            poll(lambda: considered_all(Session), 20, "the route past the acknowledgement")
            assert len(receiver.requests) == n, "a shelved alarm's acknowledgement was sent"
            with Session() as s:
                silenced = s.scalars(select(NotificationEventRow)
                                     .where(NotificationEventRow.kind == "acknowledged")).all()
            assert len(silenced) == 1 and silenced[0].silenced.startswith("alarm shelved until")
            r = client.post(f"/api/v1/alarms/{alarm_id}/unshelve", headers=op, json={"reason": "leak fixed?"})
            assert r.status_code == 200, r.text
            poll(lambda: [e["kind"] for e in receiver.events()][-1:] == ["unshelved"], 20, "the unshelve")
            assert [e["kind"] for e in receiver.events()] == ["raised", "shelved", "unshelved"]
            # a shelve that runs out by itself is announced once
            r = client.post(f"/api/v1/alarms/{alarm_id}/shelve", headers=op, json={"minutes": 0.02, "reason": "1.2 s"})
            assert r.status_code == 200, r.text
            poll(lambda: [e["kind"] for e in receiver.events()][3:] == ["shelved", "unshelved"], 20,
                 "the shelve's end")
            assert receiver.events()[-1]["reason"] == "the shelving time ended"
            # out of service: the clear that returning to service makes is silenced too
            adm = {"X-API-Key": keys["admin"]}
            assert client.post("/api/v1/breakers/1/out-of-service", headers=op,
                               json={"reason": "maintenance order 4711"}).status_code == 200
            n = len(receiver.requests)
            assert client.post("/api/v1/breakers/1/return-to-service", headers=adm, json={}).status_code == 200
            poll(lambda: considered_all(Session), 20, "the route past the return to service")
            assert len(receiver.requests) == n
            with Session() as s:
                cleared = s.scalars(select(NotificationEventRow).where(NotificationEventRow.kind == "cleared")).all()
            assert len(cleared) == 1 and cleared[0].silenced.startswith("breaker out of service")
        check_signed(receiver)
    finally:
        receiver.stop()


def test_email_over_starttls_with_login_and_routing_filters(tmp_path, db_url):
    """SMTP: STARTTLS, then login, then the mail; a route for another breaker or for alarms
    only gets nothing of a warning on breaker 1."""
    smtp = SmtpReceiver(tmp_path).start()
    other = WebhookReceiver().start()
    try:
        settings = make_settings(tmp_path, db_url, notifications=notifications(
            smtp.route(), webhook(other.url, name="bay2-only", breakers=["Q2"]),
            webhook(other.url, name="alarms-only", severities=["alarm"]),
            webhook(other.url, name="bo-only", parameters=["BO"])))
        with running_app(settings) as (app, client, keys):
            store(app.state.Session, 1, "raised")
            poll(lambda: smtp.messages, 20, "the e-mail")
            poll(lambda: all(considered_all(app.state.Session, n) for n in ("mail", "bay2-only", "alarms-only",
                                                                             "bo-only")), 20,
                 "every route past the event")
            with app.state.Session() as s:
                status = dict(s.execute(select(NotificationDeliveryRow.route, NotificationDeliveryRow.status)).all())
            assert status == {"mail": "sent", "bay2-only": "skipped", "alarms-only": "skipped", "bo-only": "skipped"}
        mail = smtp.messages[0]
        assert smtp.logins == [SmtpReceiver.user]
        assert "WARNING raised" in mail["Subject"] and "reference-252kV" in mail["Subject"]
        assert mail["To"] == "asset.engineer@utility.example"
        assert "buffer damping (DO) falling" in mail.get_payload(decode=True).decode()
        assert other.requests == [], "a filtered route was sent the event"
    finally:
        smtp.stop()
        other.stop()


def test_a_chat_route_through_apprise_posts_the_text(tmp_path, db_url):
    """Apprise (the chat services' library) delivers the same text; its generic json:// service
    stands in for Teams, Slack or Matrix here, posting to the loopback receiver."""
    pytest.importorskip("apprise", reason="apprise lane off: pip install 'hvcb[notify]'")
    chat = WebhookReceiver().start()
    try:
        url = chat.url.replace("http://", "json://")
        settings = make_settings(tmp_path, db_url, notifications=notifications(
            {"name": "chat", "kind": "apprise", "urls": [url]}))
        with running_app(settings) as (app, client, keys):
            store(app.state.Session, 1, "raised")
            posted = poll(lambda: chat.messages(), 20, "the chat message")
            poll(lambda: considered_all(app.state.Session, "chat"), 20, "the chat route done")
    finally:
        chat.stop()
    assert len(posted) == 1
    assert posted[0]["title"].startswith("[hvcb] WARNING raised: reference-252kV (Q1) DO")
    assert "buffer damping (DO) falling" in posted[0]["message"]


def test_events_are_written_with_their_transition_and_rolled_back_with_it(tmp_path, db_url):
    """The outbox row is part of the alarm transition's transaction: a rolled-back transition
    leaves no event; a committed one leaves exactly its events. A route configured later is not
    sent the past."""
    from service.jobs.fit import apply_alarm_event
    from service.notifications import outbox
    from service.notifications.routes import RouteSettings
    from service.storage.db import make_engine, session_factory

    engine = make_engine(db_url)
    Session = session_factory(engine)
    try:
        with Session() as s, s.begin():
            crud.upsert_breaker(s, name="bay1", tag="Q1", breaker_file="x", cam_file_name="", cam_table="")
        ev = AlarmEvent("raised", "DO", "warning", 1, None, utcnow(), {})
        with Session() as s:
            s.begin()
            apply_alarm_event(s, breaker_id=1, event=ev)
            assert s.scalar(select(func.count()).select_from(NotificationEventRow)) == 1  # inside the transaction
            s.rollback()
        with Session() as s:
            assert s.scalar(select(func.count()).select_from(NotificationEventRow)) == 0
        store(Session, 1, "raised")
        store(Session, 1, "escalated", level="alarm")
        with Session() as s, s.begin():
            assert [e.kind for e in s.scalars(select(NotificationEventRow).order_by(NotificationEventRow.id))] == \
                ["raised", "escalated"]
            late = RouteSettings(name="late", kind="webhook", url="http://127.0.0.1:9/x", secret="s" * 20)
            assert outbox.take_in(s, late, now=utcnow()) == 0 and outbox.unconsidered(s, "late") == 0
        store(Session, 1, "cleared", level="alarm")
        with Session() as s, s.begin():
            assert outbox.take_in(s, late, now=utcnow()) == 1
    finally:
        engine.dispose()


def test_a_prognosis_entering_its_last_weeks_makes_one_event_and_leaving_another(tmp_path, db_url):
    from datetime import timedelta

    from service.notifications import watch
    from service.storage.db import make_engine, session_factory
    from service.storage.models import PrognosisRow

    engine = make_engine(db_url)
    Session = session_factory(engine)
    now = utcnow()

    def result(weeks):
        when = (now + timedelta(weeks=weeks)).isoformat()
        return {"status": "ok", "limit_text": "DO min_change = -0.25",
                "date_to_limit": {"p05": when, "median": when, "p95": when},
                "operations_to_limit": {"p05": 10.0, "median": 20.0, "p95": 30.0}}

    try:
        with Session() as s, s.begin():
            crud.upsert_breaker(s, name="bay1", tag="Q1", breaker_file="x", cam_file_name="", cam_table="")
            s.add(PrognosisRow(breaker_id=1, parameter="DO", median_operations=20.0, result=result(30)))
        kinds = []
        for weeks in (30, 11, 10, 9, 13, 13, 5):
            with Session() as s, s.begin():
                s.get(PrognosisRow, (1, "DO")).result = result(weeks)
            with Session() as s, s.begin():
                watch.prognosis_windows(s, weeks=12, now=now)
                kinds = [e.kind for e in s.scalars(select(NotificationEventRow).order_by(NotificationEventRow.id))]
        assert kinds == ["prognosis_entered", "prognosis_left", "prognosis_entered"]
        with Session() as s:
            first = s.scalars(select(NotificationEventRow).order_by(NotificationEventRow.id)).first()
        assert first.payload["prognosis"]["window_weeks"] == 12 and first.payload["parameter"] == "DO"
        assert first.severity == "warning" and first.silenced is None
    finally:
        engine.dispose()
