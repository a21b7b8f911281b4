"""``hvcb agent``: the DAQs, the outbox, the forwarder and the metrics of one substation box."""

from __future__ import annotations

import logging
from datetime import datetime, timezone
from pathlib import Path

from prometheus_client import CollectorRegistry
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily

from service.acquisition.daq_runner import DaqGroup, DaqRunner

from .forwarder import Forwarder
from .outbox import Outbox

log = logging.getLogger("hvcb.agent")


class Agent:
    """Acquisition only: each capture is made durable, journalled in the outbox and forwarded."""

    def __init__(self, settings, *, transport=None):
        from service.breaker_file import load_breaker

        self.settings = settings
        breakers = {}
        for path in settings.breakers:
            b = load_breaker(Path(path))
            breakers[b.name] = b
        self.outbox = Outbox(settings.outbox_dir, settings.capture_dir, max_bytes=settings.spool_max_bytes)
        runners = []
        for acq in settings.acquisition:
            breaker = breakers.get(acq.breaker) if acq.breaker else next(iter(breakers.values()))
            if breaker is None:
                raise ValueError(f"[[acquisition]] breaker {acq.breaker!r} is not among the agent's `breakers` files")
            if breaker.name not in settings.central.breaker_ids:
                raise ValueError(f"breaker {breaker.name!r} has no id in [central] breaker_ids")
            runners.append(DaqRunner(acq, breaker, settings.capture_dir / breaker.name,
                                     on_capture=self._spool_for(breaker.name)))
        self.daqs = DaqGroup(runners)
        self.forwarder = Forwarder(self.outbox, settings.central, transport=transport)
        self.registry = CollectorRegistry()
        self.registry.register(_AgentCollector(self))
        self._metrics_server = None

    def _spool_for(self, breaker: str):
        def spool(cfg_path, detected) -> None:
            captured = detected.capture.start_time or datetime.now(timezone.utc)
            entry = self.outbox.put(cfg_path, breaker=breaker, operation=detected.operation, captured_at=captured)
            if entry is not None:
                log.info("captured %s (%s); %d in the outbox", Path(cfg_path).name, detected.operation,
                         len(self.outbox))
        return spool

    def start(self) -> None:
        if self.settings.metrics_port:
            from prometheus_client import start_http_server

            self._metrics_server = start_http_server(self.settings.metrics_port, addr=self.settings.metrics_host,
                                                     registry=self.registry)
        self.forwarder.start()
        self.daqs.start()

    def stop(self) -> None:
        self.daqs.stop()
        self.forwarder.stop()
        if self._metrics_server is not None:
            server, thread = self._metrics_server
            server.shutdown()
            server.server_close()
            thread.join(timeout=5)
            self._metrics_server = None


class _AgentCollector:
    def __init__(self, agent: Agent):
        self.agent = agent

    def collect(self):
        from service.acquisition.daq_metrics import daq_state_metrics

        a, ob, fw = self.agent, self.agent.outbox, self.agent.forwarder
        yield GaugeMetricFamily("hvcb_agent_spool_depth", "captures waiting to be forwarded", value=len(ob))
        yield GaugeMetricFamily("hvcb_agent_spool_bytes", "bytes of captures waiting", value=ob.bytes)
        yield GaugeMetricFamily("hvcb_agent_spool_max_bytes", "outbox bound", value=ob.max_bytes)
        yield GaugeMetricFamily("hvcb_agent_spool_full", "1 when the outbox refused the last capture (alarm)",
                                value=1 if ob.full else 0)
        yield GaugeMetricFamily("hvcb_agent_oldest_unsent_age_seconds",
                                "age of the oldest capture not yet accepted by the central server",
                                value=ob.oldest_age_s())
        yield CounterMetricFamily("hvcb_agent_captures_dropped", "captures refused because the outbox was full",
                                  value=ob.dropped)
        yield CounterMetricFamily("hvcb_agent_captures_forwarded", "captures accepted by the central server",
                                  value=ob.sent_count)
        yield CounterMetricFamily("hvcb_agent_captures_rejected", "captures the central server refused for good",
                                  value=ob.rejected)
        yield CounterMetricFamily("hvcb_agent_upload_failures", "upload attempts that failed and will be retried",
                                  value=fw.failures)
        yield GaugeMetricFamily("hvcb_agent_central_up", "1 when the central server answered the last upload",
                                value=1 if fw.central_up else 0)
        yield from daq_state_metrics(a.daqs)
