"""Notifications: alarm and prognosis events delivered to people and systems (docs/notifications.md).

- ``events``: the kinds and the JSON form of an event; ``schema``: the webhook body's JSON Schema
- ``rows``: the outbox tables (migration 0013); ``capture``: alarm transitions → outbox rows, in
  the transition's own transaction
- ``routes``: the ``[notifications]`` settings and routing; ``outbox``: take in, form a message,
  mark it sent or failed; ``retry``: backoff; ``watch``: shelve expiries and prognosis windows
- ``message``, ``signature``: the message and its HMAC; ``webhook``, ``smtp``, ``chat``: transports
- ``notifier``: the threads that run it all beside the service
"""
