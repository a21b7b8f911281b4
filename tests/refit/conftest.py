# The service fixtures (db_url per backend, breaker) serve the refit tests too.
from tests.service.conftest import breaker, db_url, pg_server  # noqa: F401
