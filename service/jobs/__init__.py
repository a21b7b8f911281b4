"""Work the service does on each capture: durable ingest, the fit job, the diagnosis job."""

# Every process that stores alarm transitions imports this package (API, local pool, Celery
# workers, commands): hook the outbox here, so each transition writes its notification events
# in its own transaction (service.notifications.capture).
from service.notifications import capture as _capture  # noqa: E402

_capture.install()
