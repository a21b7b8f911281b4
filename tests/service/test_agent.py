"""The edge agent end to end: `hvcb agent` (a real process) reads a Modbus TCP DAQ emulator and
forwards to a central hvcb (uvicorn, SQLite) through the upload API with an `agent` key.

The central server is stopped mid-stream for OUTAGE_S and started again: every capture arrives
exactly once, in order. Then the agent is SIGKILLed with captures pending and restarted: still
nothing lost or doubled. The suite runs a 5 s outage; the `slow` case (run by CI) the full 60 s.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

import httpx
import pytest

from conftest import BREAKER_FILE, make_settings
from fleet_helpers import Central, ModbusDaq, capture_block, free_port, poll
from service.storage import crud
from service.storage.db import upgrade

REPO = Path(__file__).resolve().parents[2]


def _metric(port: int, name: str) -> float | None:
    try:
        text = httpx.get(f"http://127.0.0.1:{port}/metrics", timeout=2).text
    except httpx.HTTPError:
        return None
    for line in text.splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    return None


class AgentProcess:
    def __init__(self, config: Path, log: Path):
        self.config, self.log = config, log
        self.proc = None

    def start(self) -> None:
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        self.fh = open(self.log, "a")
        self.proc = subprocess.Popen([sys.executable, "-m", "service.cli", "agent", "--config", str(self.config)],
                                     cwd=REPO, env=env, stdout=self.fh, stderr=subprocess.STDOUT)

    def kill(self) -> None:
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(30)
        self.fh.close()

    def terminate(self) -> int:
        self.proc.send_signal(signal.SIGTERM)
        code = self.proc.wait(60)
        self.fh.close()
        return code


def _operations(central: Central):
    from sqlalchemy import select

    from service.storage.models import OperationRow

    with central.app.state.Session() as s:
        return list(s.scalars(select(OperationRow).order_by(OperationRow.id)))


def _edge_toml(tmp_path, modbus_port, central_url, key, metrics_port) -> Path:
    p = tmp_path / "edge.toml"
    p.write_text(f'''data_dir = "{tmp_path / 'edge'}"
breakers = ["{BREAKER_FILE}"]
metrics_port = {metrics_port}

[[acquisition]]
driver = "modbus"
breaker = "reference-252kV"
[acquisition.modbus]
host = "127.0.0.1"
port = {modbus_port}
poll_interval_s = 0.1
timeout_s = 1.0

[central]
url = "{central_url}"
api_key = "{key}"
breaker_ids = {{ "reference-252kV" = 1 }}
retry_min_s = 0.2
retry_max_s = 2.0
timeout_s = 5.0
''')
    return p


@pytest.mark.parametrize("outage_s", [5.0, pytest.param(60.0, marks=pytest.mark.slow)])
def test_agent_survives_central_outage_and_sigkill(tmp_path, breaker, outage_s):
    url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    (tmp_path / "data").mkdir()
    upgrade(url)
    central = Central(make_settings(tmp_path, url, breakers=[BREAKER_FILE], port=free_port(),
                                    fit_function="fleet_helpers:no_fit"))
    central.start()
    with central.app.state.Session() as s, s.begin():
        key = crud.create_api_key(s, name="edge-1", role="agent")[1]
    daq = ModbusDaq(breaker)
    metrics_port = free_port()
    agent = AgentProcess(_edge_toml(tmp_path, daq.port, central.url, key, metrics_port), tmp_path / "agent.log")
    agent.start()
    seed = iter(range(100, 200))
    sent = 0

    def add(n):
        nonlocal sent
        for _ in range(n):
            daq.add(capture_block(breaker, "open", next(seed), sent * 10_000_000))
            sent += 1
            poll(lambda: daq.acknowledged >= sent, 60, f"the agent to download capture {sent}")

    def depth():
        return _metric(metrics_port, "hvcb_agent_spool_depth")

    try:
        # -- streaming normally ---------------------------------------------------------------
        add(2)
        poll(lambda: len(_operations(central)) == 2, 60, "the first two captures at the central server")

        # -- the central server is down for outage_s; captures keep coming ----------------------
        central.stop()
        down_at = time.monotonic()
        add(3)
        poll(lambda: depth() == 3, 30, "three captures in the agent's outbox")
        assert _metric(metrics_port, "hvcb_agent_central_up") == 0.0
        remaining = outage_s - (time.monotonic() - down_at)
        if remaining > 0:
            time.sleep(remaining)  # the outage itself, not a synchronisation
        age = _metric(metrics_port, "hvcb_agent_oldest_unsent_age_seconds")
        assert age is not None and age >= outage_s - 2.0, age
        central.start()
        poll(lambda: len(_operations(central)) == 5 and depth() == 0, 60 + outage_s,
             "the outbox drained into the central server")

        # -- the agent is SIGKILLed with captures pending, one more captured while it is dead ----
        central.stop()
        add(2)
        poll(lambda: depth() == 2, 30, "two captures pending in the agent's outbox")
        agent.kill()
        daq.add(capture_block(breaker, "open", next(seed), sent * 10_000_000))
        sent += 1
        agent.start()
        poll(lambda: depth() == 3, 60, "the restarted agent with its two pending captures and the new one")
        central.start()
        poll(lambda: len(_operations(central)) == 8 and depth() == 0, 60, "everything at the central server")

        ops = _operations(central)
        assert len(ops) == sent == 8 == daq.acknowledged
        assert len({o.capture_key for o in ops}) == 8  # each capture once
        assert all(o.source == "agent" and o.breaker_id == 1 and o.kind == "open" for o in ops)
        times = [o.occurred_at for o in ops]
        assert times == sorted(times) and len(set(times)) == 8  # stored in capture order
        assert all(isinstance(t, datetime) for t in times)
        assert _metric(metrics_port, "hvcb_agent_captures_dropped_total") == 0.0
        assert agent.terminate() == 0
    finally:
        if agent.proc is not None and agent.proc.poll() is None:
            agent.kill()
        central.stop()
        daq.kill()
