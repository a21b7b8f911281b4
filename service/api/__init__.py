"""The REST API: app factory, routes, schemas, auth; ``commands.py`` holds ``hvcb serve`` and ``hvcb demo``."""
