"""The notifications' pure pieces: signatures, backoff, which transitions make which events,
what silences them, route settings and filters, grouping into messages, the documented schema."""

from __future__ import annotations

import json
import re
from datetime import datetime, timedelta, timezone
from pathlib import Path

import jsonschema
import pytest
from pydantic import ValidationError

from service.notifications import events as ev
from service.notifications.message import body, body_bytes, message_key, subject, text
from service.notifications.retry import backoff_s
from service.notifications.routes import NotificationSettings, RouteSettings
from service.notifications.schema import SCHEMA
from service.notifications.signature import sign, verify

ROOT = Path(__file__).resolve().parents[2]
NOW = datetime(2026, 11, 28, 3, 0, tzinfo=timezone.utc)
SECRET = "0123456789abcdef0123"


def test_signature_verifies_only_the_same_body_secret_and_a_fresh_timestamp():
    b = b'{"events":[]}'
    sig = sign(SECRET, 1_800_000_000, b)
    assert sig.startswith("v1=") and len(sig) == 3 + 64
    assert verify(SECRET, timestamp="1800000000", signature=sig, body=b, now=1_800_000_010)
    assert not verify(SECRET, timestamp="1800000000", signature=sig, body=b + b" ", now=1_800_000_010)
    assert not verify("another-secret-0123", timestamp="1800000000", signature=sig, body=b, now=1_800_000_010)
    assert not verify(SECRET, timestamp="1800000001", signature=sig, body=b, now=1_800_000_010)  # re-dated
    assert not verify(SECRET, timestamp="1800000000", signature=sig, body=b, now=1_800_000_000 + 301)  # replayed
    assert not verify(SECRET, timestamp="soon", signature=sig, body=b, now=1_800_000_000)
    # the documented recipe (docs/notifications.md) gives the same signature
    import hashlib
    import hmac
    assert sig == "v1=" + hmac.new(SECRET.encode(), b"1800000000." + b, hashlib.sha256).hexdigest()


def test_backoff_doubles_from_the_first_wait_up_to_the_longest():
    assert [backoff_s(n, first_s=1, max_s=600) for n in range(0, 12)] == [0, 1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 600]
    assert backoff_s(10_000, first_s=1, max_s=600) == 600


@pytest.mark.parametrize("old, new, kinds", [
    ({"state": "raised"}, {"state": "acknowledged", "level": "warning", "shelved_until": None}, ["acknowledged"]),
    ({"state": "acknowledged", "level": "warning"}, {"state": "raised", "level": "alarm", "shelved_until": None},
     ["escalated"]),
    ({"state": "raised"}, {"state": "cleared", "level": "alarm", "shelved_until": None}, ["cleared"]),
    ({"shelved_until": None}, {"state": "raised", "level": "alarm", "shelved_until": NOW + timedelta(hours=1)},
     ["shelved"]),
    ({"shelved_until": NOW + timedelta(hours=1)}, {"state": "raised", "level": "alarm", "shelved_until": NOW},
     ["unshelved"]),
    ({"shelved_until": NOW + timedelta(hours=1), "level": "warning"},
     {"state": "raised", "level": "alarm", "shelved_until": NOW}, ["unshelved", "escalated"]),
    ({"state": "raised", "level": "alarm"}, {"state": "raised", "level": "alarm", "shelved_until": None}, []),
    ({"shelved_until": NOW - timedelta(hours=1)}, {"state": "raised", "level": "alarm", "shelved_until": NOW}, []),
])
def test_a_stored_change_makes_the_events_of_its_transitions(old, new, kinds):
    assert ev.alarm_transitions(inserted=False, old=old, new=new, now=NOW) == kinds


def test_shelving_and_out_of_service_silence_everything_but_the_shelve_and_its_end():
    until = NOW + timedelta(hours=2)
    for kind in ("acknowledged", "cleared", "escalated", "raised"):
        assert ev.silenced_reason(kind, shelved_until=until, out_of_service_since=None, now=NOW).startswith(
            "alarm shelved until 2026-11-28T05:00:00Z")
    for kind in ("shelved", "unshelved"):
        assert ev.silenced_reason(kind, shelved_until=until, out_of_service_since=None, now=NOW) is None
    assert ev.silenced_reason("acknowledged", shelved_until=NOW, out_of_service_since=None, now=NOW) is None
    assert ev.silenced_reason("shelved", shelved_until=until, out_of_service_since=NOW, now=NOW).startswith(
        "breaker out of service")


def route(**kw) -> RouteSettings:
    return RouteSettings(**{"name": "r", "kind": "webhook", "url": "https://x.example/h", "secret": SECRET, **kw})


def test_routes_filter_by_breaker_name_or_tag_parameter_severity_and_kind():
    b = {"id": 1, "name": "reference-252kV", "tag": "Q1"}
    assert route().matches(kind="raised", severity="warning", parameter="DO", breaker=b)
    assert route(breakers=["Q1"]).matches(kind="raised", severity="warning", parameter="DO", breaker=b)
    assert route(breakers=["reference-252kV"]).matches(kind="raised", severity="warning", parameter="DO", breaker=b)
    assert not route(breakers=["Q2"]).matches(kind="raised", severity="warning", parameter="DO", breaker=b)
    assert not route(parameters=["BO"]).matches(kind="raised", severity="warning", parameter="DO", breaker=b)
    assert not route(severities=["alarm"]).matches(kind="raised", severity="warning", parameter="DO", breaker=b)
    assert route(severities=["alarm"]).matches(kind="escalated", severity="alarm", parameter="DO", breaker=b)
    assert not route(events=["raised"]).matches(kind="cleared", severity="warning", parameter="DO", breaker=b)


@pytest.mark.parametrize("kw, words", [
    ({"secret": "short"}, "at least 16 random characters"),
    ({"secret": "changeme"}, "at least 16"),
    ({"url": "ftp://x"}, "needs url"),
    ({"kind": "email", "smtp_host": "mail.example"}, "e-mail needs smtp_host, sender and to"),
    ({"kind": "email", "smtp_host": "m", "sender": "a@b", "to": ["c@d"], "username": "u", "starttls": False},
     "never sent in the clear"),
    ({"kind": "apprise"}, "apprise needs urls"),
    ({"secret": "", "secret_env": "HVCB_TEST_UNSET_SECRET_VARIABLE"}, "HVCB_TEST_UNSET_SECRET_VARIABLE is empty"),
    ({"events": ["exploded"]}, "events"),
])
def test_bad_routes_are_refused_in_words(kw, words):
    with pytest.raises(ValidationError) as exc:
        route(**kw)
    assert words in str(exc.value)


def test_a_secret_may_come_from_the_environment(monkeypatch):
    monkeypatch.setenv("HVCB_TEST_HOOK_SECRET", "from-the-environment-123")
    assert route(secret="", secret_env="HVCB_TEST_HOOK_SECRET").secret == "from-the-environment-123"
    assert "from-the-environment" not in repr(route(secret="", secret_env="HVCB_TEST_HOOK_SECRET"))


def test_settings_refuse_two_routes_of_one_name():
    with pytest.raises(ValidationError, match="same name"):
        NotificationSettings(routes=[route().model_dump(), route().model_dump()])


def _event(kind="raised", breaker=("reference-252kV", "Q1"), seq=1, severity="warning"):
    alarm = {"id": 7, "parameter": "DO", "level": severity, "state": "raised", "episode": 1,
             "message": "WARNING: buffer damping factor DO falling (-6.0 % from baseline); likely buffer oil leak",
             "raised_at": NOW, "first_out": True, "shelved_until": None, "operation_id": 42}
    e = ev.alarm_payload(kind, key=f"k{seq}", alarm=alarm, breaker={"id": 1, "name": breaker[0], "tag": breaker[1]},
                         now=NOW)
    return {**e, "sequence": seq}


def test_a_message_validates_and_its_bytes_and_key_are_stable():
    one = body(message_key(["k1"]), [_event()])
    jsonschema.validate(one, SCHEMA)
    assert one["message_id"] == "k1"
    storm = [_event(seq=i, breaker=(f"bay{i % 3}", None)) for i in range(1, 8)]
    group = body(message_key([e["id"] for e in storm]), storm)
    jsonschema.validate(group, SCHEMA)
    assert group["message_id"] == message_key([e["id"] for e in storm]) != message_key([e["id"] for e in storm[:-1]])
    assert body_bytes(group) == body_bytes(json.loads(body_bytes(group)))
    assert subject(storm) == "[hvcb] WARNING: 7 events on 3 breakers"
    assert subject([_event()]).startswith("[hvcb] WARNING raised: reference-252kV (Q1) DO: WARNING: buffer damping")
    assert text(storm).startswith("7 events grouped: 7 raised\n")
    bad = dict(one, events=[{**_event(), "kind": "exploded"}])
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, SCHEMA)


def test_prognosis_events_say_when_and_validate():
    result = {"status": "ok", "limit_text": "DO min_change = -0.25",
              "date_to_limit": {"p05": "2027-01-02T00:00:00+00:00", "median": "2027-01-20T00:00:00+00:00",
                                "p95": "2027-02-20T00:00:00+00:00"},
              "operations_to_limit": {"p05": 80.0, "median": 120.0, "p95": 200.0}}
    e = ev.prognosis_payload("prognosis_entered", key="p1", breaker={"id": 1, "name": "b", "tag": None},
                             parameter="DO", weeks=12, result=result, now=NOW)
    jsonschema.validate(body("p1", [{**e, "sequence": 3}]), SCHEMA)
    assert ev.headline(e) == ("PROGNOSIS: b DO expected at its limit (DO min_change = -0.25) within 12 weeks "
                              "(median 2027-01-20)")
    from service.notifications.watch import within

    assert within(result, weeks=12, now=NOW) and not within(result, weeks=6, now=NOW)
    assert within({"status": "crossed"}, weeks=1, now=NOW) and not within({"status": "no trend"}, weeks=99, now=NOW)


def test_the_documented_schema_is_the_one_the_notifier_sends():
    page = (ROOT / "docs" / "notifications.md").read_text(encoding="utf-8")
    block = re.search(r"<!-- schema -->\s*```json\n(.*?)```", page, re.S)
    assert block, "docs/notifications.md lost its schema block"
    assert json.loads(block.group(1)) == json.loads(json.dumps(SCHEMA))
