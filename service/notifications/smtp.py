"""E-mail transport: stdlib ``smtplib`` and ``email``, STARTTLS before authentication.

The connection is upgraded with STARTTLS (certificate and host name checked against the system's
CAs or the route's ``ca_file``) before the password or any text is sent; a server that does not
offer STARTTLS is a failure, not a fallback to plain text. Message-ID is the idempotency key.
"""

from __future__ import annotations

import smtplib
import ssl
from email.message import EmailMessage
from email.utils import formatdate

from service.errors import in_words
from service.notifications.delivery_error import DeliveryError
from service.notifications.message import subject, text


def build(route, message: dict) -> EmailMessage:
    events = message["events"]
    mail = EmailMessage()
    mail["From"] = route.sender
    mail["To"] = ", ".join(route.to)
    mail["Subject"] = subject(events)
    mail["Date"] = formatdate(usegmt=True)
    mail["Message-ID"] = f"<{message['message_id']}@hvcb>"
    mail["X-Hvcb-Events"] = ",".join(e["id"] for e in events)
    mail.set_content(text(events, message.get("page_url") or ""))
    return mail


def send(route, message: dict) -> None:
    mail = build(route, message)
    context = ssl.create_default_context(cafile=str(route.ca_file) if route.ca_file else None)
    try:
        with smtplib.SMTP(route.smtp_host, route.smtp_port, timeout=route.timeout_s) as smtp:
            smtp.ehlo()
            if route.starttls:
                if not smtp.has_extn("starttls"):
                    raise DeliveryError(f"SMTP server {route.smtp_host}:{route.smtp_port} does not offer STARTTLS")
                smtp.starttls(context=context)
                smtp.ehlo()
            if route.username:
                smtp.login(route.username, route.password)
            smtp.send_message(mail)
    except DeliveryError:
        raise
    except smtplib.SMTPAuthenticationError as exc:
        raise DeliveryError(f"SMTP server {route.smtp_host} refused the login of {route.username!r} "
                            f"({exc.smtp_code})") from None
    except smtplib.SMTPException as exc:
        raise DeliveryError(f"SMTP server {route.smtp_host}:{route.smtp_port}: {exc}") from None
    except ssl.SSLError as exc:
        raise DeliveryError(f"SMTP server {route.smtp_host}: TLS failed ({exc.reason or exc})") from None
    except OSError as exc:  # refused, unreachable, timed out
        raise DeliveryError(f"SMTP server {route.smtp_host}:{route.smtp_port} not reached: {in_words(exc)}") from None
