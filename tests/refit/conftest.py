# The service fixtures (db_url per backend, an app with a key per role) serve the refit tests too.
from tests.service.conftest import breaker, db_url, env, no_leaked_threads, pg_server  # noqa: F401
