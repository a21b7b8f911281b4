"""Chat transport through Apprise (Teams, Slack, Matrix, ntfy, Telegram, ... one URL each).

Apprise is optional (``pip install hvcb[notify]``): a route of kind ``apprise`` without it fails
its attempts with a message saying so, and its events wait in the outbox.
"""

from __future__ import annotations

from service.notifications.delivery_error import DeliveryError
from service.notifications.message import subject, text


def send(route, message: dict) -> None:
    try:
        import apprise
    except ImportError:
        raise DeliveryError(f"route {route.name!r} needs the apprise package: pip install 'hvcb[notify]'") from None
    events = message["events"]
    ap = apprise.Apprise()
    for url in route.urls:
        if not ap.add(url):
            raise DeliveryError(f"route {route.name!r}: apprise does not understand one of its urls")
    if not ap.notify(title=subject(events), body=text(events, message.get("page_url") or "")):
        raise DeliveryError(f"route {route.name!r}: apprise could not deliver to every url (see the log)")
