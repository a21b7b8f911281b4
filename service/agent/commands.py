"""``hvcb agent --config edge.toml``."""

from __future__ import annotations

import signal
import threading


def register(sub) -> None:
    p = sub.add_parser("agent", help="edge agent: DAQs, trigger and a durable outbox; forwards every capture "
                                     "to a central hvcb over HTTPS")
    p.add_argument("--config", required=True, help="agent settings TOML (see config/edge.toml)")
    p.set_defaults(func=cmd_agent)


def cmd_agent(args) -> int:
    import logging

    from pydantic import ValidationError

    from service.errors import UserError

    from .runner import Agent
    from .settings import load_agent_settings

    try:
        settings = load_agent_settings(args.config)
    except ValidationError as exc:
        raise UserError(f"bad agent settings in {args.config}: " + "; ".join(
            f"{'.'.join(map(str, e['loc'])) or 'file'}: {e['msg'].removeprefix('Value error, ')}" for e in exc.errors())) from None
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("httpx").setLevel(logging.WARNING)
    # pymodbus logs every timed-out read with a hex dump; the driver reports its retries itself.
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    agent = Agent(settings)
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    agent.start()
    print(f"hvcb agent: {len(settings.acquisition)} DAQ(s) → {settings.central.url}; "
          f"{len(agent.outbox)} capture(s) in the outbox"
          + (f"; metrics on http://{settings.metrics_host}:{settings.metrics_port}/metrics"
             if settings.metrics_port else ""), flush=True)
    try:
        stop.wait()
    finally:
        agent.stop()
    return 0
