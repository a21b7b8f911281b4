"""Prometheus metric families of this process's DAQs (their ``DaqState``), for the service's
``/metrics`` and the edge agent's metrics port alike."""

from __future__ import annotations

from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily


def daq_state_metrics(daqs):
    """Live per-DAQ health (``DaqState``) of this process's DAQs, labelled by DAQ name."""
    states = daqs.states() if daqs is not None and getattr(daqs, "enabled", False) else []
    up = GaugeMetricFamily("hvcb_daq_up", "1 when this DAQ's driver runs and its link is connected",
                           labels=["daq", "breaker", "driver"])
    down = GaugeMetricFamily("hvcb_daq_down", "1 when this DAQ is failing or disconnected",
                             labels=["daq", "breaker", "driver"])
    restarts = CounterMetricFamily("hvcb_daq_restarts", "driver rebuilds after a failure (with backoff)",
                                   labels=["daq"])
    caps = CounterMetricFamily("hvcb_daq_run_captures", "captures handed on by this DAQ since start",
                               labels=["daq"])
    errs = CounterMetricFamily("hvcb_daq_capture_errors", "captures written but not handed on", labels=["daq"])
    for st in states:
        lab = [st.name, st.breaker, st.driver]
        up.add_metric(lab, 1 if st.up else 0)
        down.add_metric(lab, 1 if st.down else 0)
        restarts.add_metric([st.name], st.restarts)
        caps.add_metric([st.name], st.captures)
        errs.add_metric([st.name], st.capture_errors)
    yield from (up, down, restarts, caps, errs)
