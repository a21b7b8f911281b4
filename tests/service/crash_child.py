"""A service process for the crash test: ingests captures with slow fits, then waits to be killed."""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from conftest import make_settings, synth  # noqa: E402

from service.breaker_file import load_breaker  # noqa: E402
from service.jobs.ingest import Monitor  # noqa: E402
from service.storage import crud  # noqa: E402
from service.storage.db import make_engine, session_factory  # noqa: E402
from service.workers import make_executor  # noqa: E402

tmp, url, n = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
if len(sys.argv) > 4 and sys.argv[4] == "--celery":  # queue, key prefix: the Celery lane's worker fits
    import os

    from service.settings import load_settings  # noqa: E402

    settings = load_settings(data_dir=tmp / "data", database_url=url, broker_url=os.environ["HVCB_TEST_REDIS_URL"],
                             executor="celery", celery_queue=sys.argv[5], celery_key_prefix=sys.argv[6])
else:
    settings = make_settings(tmp, url, executor="local", fit_function="fit_doubles:slow_fit")
Session = session_factory(make_engine(url))
breaker = load_breaker(settings.breakers[0])
with Session() as s, s.begin():
    crud.register_breaker_file(s, path=settings.breakers[0])
monitor = Monitor(settings, Session, make_executor(settings))
monitor.start()
for i in range(n):
    monitor.ingest(synth(breaker, "open", i), breaker_id=1, operation="open")
print("ingested", flush=True)
time.sleep(600)
