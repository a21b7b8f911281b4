"""The embedded demo's scripted history: a healthy baseline, then a slow buffer oil leak.

Each step is one opening (and every third step a closing too) of the reference breaker,
synthesised from the project's models with DO falling once the leak starts. The captures go
through the same path a DAQ capture takes: ``Monitor.ingest`` (durable file → row → fit job).
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from datetime import datetime, timezone

import numpy as np

from service.acquisition.synthetic import synthesize_capture

log = logging.getLogger("hvcb.demo")


@dataclass(frozen=True)
class DemoScript:
    healthy_ops: int = 24          # operations before the leak starts
    leak_per_op: float = 0.015     # relative DO loss per operation once leaking
    total_ops: int = 60
    close_every: int = 3           # a closing after every n-th opening
    interval_s: float = 1.5        # wall time between operations
    jitter_rel: float = 0.004      # operation-to-operation scatter of the parameters
    seed: int = 7

    def parameters(self, breaker, i: int, rng) -> dict:
        p = dict(breaker.design_parameters())
        for k in p:
            p[k] *= 1.0 + rng.normal(0.0, self.jitter_rel)
        if i >= self.healthy_ops:
            p["DO"] *= (1.0 - self.leak_per_op) ** (i - self.healthy_ops + 1)
        return p


def play(monitor, *, breaker_id: int, breaker, script: DemoScript, stop: threading.Event,
         report_daq=None) -> int:
    """Feed the scripted history to ``monitor``; returns the operations sent."""
    rng = np.random.default_rng(script.seed)
    sent = 0
    for i in range(script.total_ops):
        if stop.is_set():
            break
        p = script.parameters(breaker, i, rng)
        kinds = ["open"] + (["close"] if (i + 1) % script.close_every == 0 else [])
        for j, kind in enumerate(kinds):
            cap, _ = synthesize_capture(breaker, kind, p, rng=rng)
            t = datetime.now(timezone.utc)
            cap = type(cap)(**{**cap.__dict__, "start_time": t, "source": f"demo-{kind}-{i}"})
            monitor.ingest(cap, breaker_id=breaker_id, operation=kind, source="daq")
            sent += 1
        if report_daq is not None:
            report_daq(sent)
        if stop.wait(script.interval_s):
            break
    return sent
