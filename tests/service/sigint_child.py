"""The service under uvicorn for the Ctrl-C test: ingests captures whose fits are slow, then serves
until SIGINT. Arguments: tmp dir, database URL, number of captures, port."""

import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

import uvicorn  # noqa: E402
from conftest import make_settings, synth  # noqa: E402

from service.api.app import create_app  # noqa: E402
from service.api.server import uvicorn_config  # noqa: E402
from service.breaker_file import load_breaker  # noqa: E402


def main() -> None:
    tmp, url, n, port = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    settings = make_settings(tmp, url, executor="local", fit_function="fit_doubles:slow_fit", port=port)
    app = create_app(settings)  # registers the settings' breaker: id 1
    server = uvicorn.Server(uvicorn_config(app, settings))

    def feed() -> None:
        while not server.started:
            time.sleep(0.05)
        breaker = load_breaker(settings.breakers[0])
        for i in range(n):
            app.state.monitor.ingest(synth(breaker, "open", i), breaker_id=1, operation="open")
        print("ingested", flush=True)

    threading.Thread(target=feed, name="feed", daemon=True).start()
    try:
        server.run()
    except KeyboardInterrupt:  # uvicorn re-raises the Ctrl-C once it has stopped: as `hvcb` does
        print("stopped", flush=True)
        sys.exit(130)
    print("stopped", flush=True)


if __name__ == "__main__":  # the fit pool's spawned workers import this file too
    main()
