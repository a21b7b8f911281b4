"""Prometheus metrics, read from the database at scrape time so they cover remote workers too."""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Counter, generate_latest
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, HistogramMetricFamily
from prometheus_client.exposition import CONTENT_TYPE_LATEST
from sqlalchemy import case, func, select
from sqlalchemy.exc import DBAPIError, OperationalError

from service.acquisition.daq_metrics import daq_state_metrics
from service.storage.models import AlarmRow, BreakerRow, DaqStatusRow, FitRow, OperationRow, utcnow

BUCKETS = (0.5, 1, 2, 5, 10, 20, 30, 60, 120, 300)


class _DbCollector:
    def __init__(self, app):
        self.app = app

    def collect(self):
        up = GaugeMetricFamily("hvcb_database_up", "1 when the database answers")
        Session = getattr(self.app.state, "Session", None)
        monitor = getattr(self.app.state, "monitor", None)
        if monitor is not None:
            yield GaugeMetricFamily("hvcb_spooled_captures", "captures waiting in the spool for the database",
                                    value=len(monitor.spool))
        yield from daq_state_metrics(getattr(self.app.state, "daq", None))
        if Session is None:
            return
        try:
            with Session() as session:
                by_status = dict(session.execute(select(FitRow.status, func.count()).group_by(FitRow.status)).all())
                by_source = dict(session.execute(select(OperationRow.source, func.count())
                                                 .group_by(OperationRow.source)).all())
                cols = [func.sum(case((FitRow.runtime_s <= b, 1), else_=0)) for b in BUCKETS]
                row = session.execute(select(func.count(FitRow.runtime_s), func.sum(FitRow.runtime_s), *cols)
                                      .where(FitRow.status == "done")).one()
                daq = session.execute(select(BreakerRow.name, DaqStatusRow).join(
                    DaqStatusRow, DaqStatusRow.breaker_id == BreakerRow.id)).all()
                from service.jobs.prognosis import soonest_by_breaker

                names = dict(session.execute(select(BreakerRow.id, BreakerRow.name)).all())
                soonest = {names[i]: v for i, v in soonest_by_breaker(session).items() if i in names}
                alarms = session.scalars(select(AlarmRow).where(AlarmRow.state.in_(("raised", "acknowledged")))).all()
                out_of_service = dict(session.execute(select(BreakerRow.name, BreakerRow.out_of_service_since)).all())
                from service.notifications.metrics import notification_metrics

                ns = getattr(self.app.state, "notification_settings", None)
                notify = notification_metrics(session, [r.name for r in ns.routes] if ns is not None else [])
        except (OperationalError, DBAPIError):
            up.add_metric([], 0)
            yield up
            return
        up.add_metric([], 1)
        yield up
        yield GaugeMetricFamily("hvcb_queue_depth", "fit jobs queued or running",
                                value=by_status.get("queued", 0) + by_status.get("running", 0))
        fits = GaugeMetricFamily("hvcb_fits", "fit jobs by status", labels=["status"])
        for st in ("queued", "running", "done", "failed"):
            fits.add_metric([st], by_status.get(st, 0))
        yield fits
        caps = CounterMetricFamily("hvcb_captures", "operations stored, by source", labels=["source"])
        for src, n in sorted(by_source.items()):
            caps.add_metric([src], n)
        yield caps
        count, total = int(row[0] or 0), float(row[1] or 0.0)
        buckets = [(str(b), int(v or 0)) for b, v in zip(BUCKETS, row[2:])] + [("+Inf", count)]
        yield HistogramMetricFamily("hvcb_fit_duration_seconds", "wall time of finished fits",
                                    buckets=buckets, sum_value=total)
        dropped = CounterMetricFamily("hvcb_frames_dropped", "DAQ frames dropped", labels=["breaker"])
        crc = CounterMetricFamily("hvcb_crc_errors", "DAQ frames with a CRC error", labels=["breaker"])
        frames = CounterMetricFamily("hvcb_frames", "DAQ frames received", labels=["breaker"])
        daq_caps = CounterMetricFamily("hvcb_daq_captures", "operations captured from the DAQ (driver counter)",
                                       labels=["breaker"])
        conn = GaugeMetricFamily("hvcb_daq_connected", "1 when the DAQ is connected", labels=["breaker"])
        for name, d in daq:
            dropped.add_metric([name], d.frames_dropped)
            crc.add_metric([name], d.crc_errors)
            frames.add_metric([name], d.frames)
            daq_caps.add_metric([name], d.captures)
            conn.add_metric([name], 1 if d.connected else 0)
        yield from (dropped, crc, frames, daq_caps, conn)
        ops = GaugeMetricFamily("hvcb_operations_to_limit", "median openings until the soonest maintenance "
                                "limit (prognosis); +Inf: no crossing within the horizon", labels=["breaker", "parameter"])
        for name, (parameter, median, _) in sorted(soonest.items()):
            ops.add_metric([name, parameter], float("inf") if median is None else median)
        yield ops
        # Alarm states (issue 38, docker/prometheus/alerts.yml): one series per active alarm.
        now = utcnow()
        active = GaugeMetricFamily("hvcb_alarm_active", "1 per active drift alarm: its level, lifecycle state "
                                   "(raised = unacknowledged) and whether it is shelved",
                                   labels=["breaker", "parameter", "level", "state", "shelved"])
        for a in alarms:
            shelved = a.shelved_until is not None and now < a.shelved_until
            active.add_metric([names.get(a.breaker_id, str(a.breaker_id)), a.parameter, a.level, a.state,
                               "true" if shelved else "false"], 1)
        yield active
        oos = GaugeMetricFamily("hvcb_breaker_out_of_service", "1 while the breaker is out of service "
                                "(maintenance: not watched)", labels=["breaker"])
        for name, since in sorted(out_of_service.items()):
            oos.add_metric([name], 0 if since is None else 1)
        yield oos
        yield from notify


class LocalMetrics:
    """Counters of jobs finished in this process (local pool)."""

    def __init__(self, registry):
        self.jobs = Counter("hvcb_local_jobs", "fit jobs finished by this process's pool", ["status"],
                            registry=registry)

    def observe(self, result: dict) -> None:
        self.jobs.labels(status=result.get("status", "unknown")).inc()


def build_registry(app):
    registry = CollectorRegistry()
    registry.register(_DbCollector(app))
    return registry, LocalMetrics(registry)


def render(registry) -> tuple[bytes, str]:
    return generate_latest(registry), CONTENT_TYPE_LATEST
