"""The service fixtures (a migrated SQLite and PostgreSQL database, the app) for the
maintenance log's API and page tests."""

from tests.service.conftest import db_url, env, no_leaked_threads, pg_server  # noqa: F401
