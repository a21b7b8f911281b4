"""Work the service does on each capture: durable ingest, the fit job, the diagnosis job."""
