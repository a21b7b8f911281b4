"""The Celery application of a fit worker, built from the settings at import.

    celery -A service.workers.celery_app worker --loglevel=INFO     # what docker/compose.yaml runs
    hvcb worker --concurrency 2                                      # the same, through the CLI

Settings as for ``hvcb serve``: ``HVCB_BROKER_URL`` (required), ``DATABASE_URL``,
``HVCB_DATA_DIR`` (the capture files, shared with the API), ``HVCB_CONFIG`` (a settings TOML
other than config/default.toml), ``HVCB_CELERY_QUEUE``.
"""

from __future__ import annotations

import os

from service.settings import load_settings

from .celery_backend import make_celery_from_settings

settings = load_settings(os.environ.get("HVCB_CONFIG") or None)
if not settings.broker_url:
    raise RuntimeError("the Celery worker needs HVCB_BROKER_URL (e.g. redis://127.0.0.1:6379/0) and the same "
                       "DATABASE_URL and HVCB_DATA_DIR as the API")

app = make_celery_from_settings(settings)

try:  # import the estimator once in the parent, so forked pool processes start warm
    import service.estimation.fit  # noqa: F401
except Exception:  # the job reports a missing estimator as the fit's failure reason
    pass

__all__ = ["app", "settings"]
