"""The embedded demo's DAQ: a Modbus TCP DAQ emulator on loopback playing a scripted history.

The history of the reference breaker: a healthy baseline, then a slow buffer oil leak (DO
falling), and from the 40th opening a trip latch that sticks more each opening (the vibration's
latch time rising, service.vibration). Each operation is made by the virtual prototype with mild physical effects (viscous
friction, sensor bow, ...) and run-to-run spread of the parameters, and queued in the emulator's
capture buffer at a modest pace; the history is simulated in a process of its own, at a lower
priority, so the emulator never takes the API's interpreter. The service reads it like a real DAQ: Modbus driver → trigger →
durable COMTRADE → ingest → fit job. Nothing here touches the service; only the Modbus port
connects the two.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from drivers.synthetic import synthesize_capture

log = logging.getLogger("hvcb.demo")

# Mild effects of a real mechanism, per operation (service.prototypes.a.Effects fields).
MILD_EFFECTS = {"open": {"viscous_friction": 0.02, "sensor_nonlinearity": 0.003, "orifice_buffer": 0.05},
                "close": {"viscous_friction": 0.02, "sensor_nonlinearity": 0.003}}


@dataclass(frozen=True)
class DemoScript:
    healthy_ops: int = 24          # openings before the leak starts
    leak_per_op: float = 0.015     # relative DO loss per opening once leaking
    total_ops: int = 60
    close_every: int = 3           # a closing after every n-th opening
    interval_s: float = 2.0        # wall time between operations [s]
    jitter_rel: float = 0.004      # operation-to-operation scatter of the parameters [-]
    seed: int = 7
    effects: dict = field(default_factory=lambda: MILD_EFFECTS)
    # The trip latch (issue 49): each opening's trip strike, the latch sticking more each opening
    # from ``latch_stick_from`` on (dried grease), so the demo's latch-time alarm can be seen.
    latch_s: float = 1.2e-3           # healthy strike-to-motion time [s]
    latch_jitter_rel: float = 0.02    # opening-to-opening scatter of it [-]
    latch_stick_from: int | None = 40  # first opening whose latch sticks (None: never)
    latch_stick_per_op: float = 0.05e-3  # the latch time's growth per opening once sticking [s]
    trip_strike_g: float = 30.0       # the strike's peak [g] (below the 50 g trigger)

    def latch_time(self, i: int, rng) -> float:
        """The strike-to-motion time [s] of opening ``i``."""
        lt = self.latch_s * (1.0 + rng.normal(0.0, self.latch_jitter_rel))
        if self.latch_stick_from is not None and i >= self.latch_stick_from:
            lt += (i - self.latch_stick_from + 1) * self.latch_stick_per_op
        return lt

    def parameters(self, breaker, i: int, rng) -> dict:
        p = dict(breaker.design_parameters())
        for k in p:
            p[k] *= 1.0 + rng.normal(0.0, self.jitter_rel)
        if i >= self.healthy_ops:
            p["DO"] *= (1.0 - self.leak_per_op) ** (i - self.healthy_ops + 1)
        return p


def _simulators(breaker, effects: dict) -> dict:
    """The virtual prototype per operation; the reduced model where an effect is refused."""
    sims = {}
    try:
        from service.prototypes.a import Effects, make_prototype_simulator
    except ImportError:
        return {"open": None, "close": None}
    for kind in ("open", "close"):
        try:
            sims[kind] = make_prototype_simulator(breaker, Effects(**effects.get(kind, {})), kind, method="fast")
        except (ValueError, TypeError) as exc:
            log.warning("demo: prototype refused for %s (%s); using the reduced model", kind, exc)
            sims[kind] = None
    return sims


def _trip_strike():
    """Prototype A's trip strike (service.prototypes.a.trip_strike), or None without the prototypes."""
    try:
        from service.prototypes.a.trip_strike import add_trip_strike
    except ImportError:
        return None
    return add_trip_strike


def history(breaker, script: DemoScript) -> Iterator[tuple[int, str, object]]:
    """``(opening number, kind, Capture)`` of the scripted history, in order."""
    import dataclasses

    rng = np.random.default_rng(script.seed)
    sims = _simulators(breaker, script.effects)
    strike = _trip_strike()
    for i in range(script.total_ops):
        p = script.parameters(breaker, i, rng)
        for kind in ["open"] + (["close"] if (i + 1) % script.close_every == 0 else []):
            try:
                cap, truth = synthesize_capture(breaker, kind, p, rng=rng, simulate=sims[kind])
            except ValueError:  # the prototype did not reach the end position: reduced model
                cap, truth = synthesize_capture(breaker, kind, p, rng=rng)
            if kind == "open" and strike is not None:
                # a generator of its own, so the rest of the history is drawn as before
                trip_rng = np.random.default_rng([script.seed, 49, i])
                cap = dataclasses.replace(cap, vibration=strike(cap.vibration, cap.sample_rate, truth.t_motion,
                                                                script.latch_time(i, trip_rng), trip_rng,
                                                                strike_g=script.trip_strike_g))
            yield i, kind, cap


def _produce(breaker, script: DemoScript, out, stop) -> None:
    """The history, made in a process of its own (``DemoDaq``): the virtual prototype's
    simulations are CPU work that must not share the API's interpreter. Each capture is put on
    ``out``; None ends it."""
    import queue
    import signal

    from service.workers.priority import lower_priority

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a terminal's Ctrl-C is the parent's to handle
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    lower_priority()  # the breaker's history waits for the service, never the other way round
    try:
        for item in history(breaker, script):
            while not stop.is_set():
                try:
                    out.put(item[2], timeout=0.5)
                    break
                except queue.Full:
                    continue
            if stop.is_set():
                return
    finally:
        out.put(None)


class _HistoryProcess:
    """``next()`` of the history from a spawned producer process, two captures ahead."""

    def __init__(self, breaker, script: DemoScript):
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")
        self._queue, self._stop = ctx.Queue(maxsize=2), ctx.Event()
        self._proc = ctx.Process(target=_produce, args=(breaker, script, self._queue, self._stop),
                                 name="hvcb-demo-history", daemon=True)
        import signal

        old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})  # until the child ignores it
        try:
            self._proc.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)

    def next(self):
        """The next capture, or None at the end of the history (or when the producer died)."""
        import queue

        while True:
            try:
                return self._queue.get(timeout=1.0)
            except queue.Empty:
                if not self._proc.is_alive():
                    return None

    def close(self) -> None:
        self._stop.set()
        self._proc.join(timeout=5)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(timeout=5)
        self._queue.close()
        self._queue.cancel_join_thread()


class DemoDaq:
    """The Modbus TCP DAQ emulator of the demo, on its own thread and event loop.

    ``start()`` returns the port; captures of the history are queued one per ``interval_s``;
    ``done`` is set when the history has been queued and downloaded; ``stop()`` ends it.
    """

    def __init__(self, breaker, script: DemoScript, *, host: str = "127.0.0.1", port: int = 0):
        self.breaker, self.script, self.host, self.port = breaker, script, host, port
        self.queued = 0
        self.done = threading.Event()
        self.error: BaseException | None = None
        self._ready = threading.Event()
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self.emulator = None

    def start(self, timeout: float = 20.0) -> int:
        self._thread = threading.Thread(target=self._run, name="hvcb-demo-daq", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout) or self.error is not None:
            self.stop()
            raise RuntimeError(f"the demo DAQ emulator did not start: {self.error}")
        return self.port

    def stop(self) -> None:
        if self._loop is not None and self._stop is not None:
            try:
                self._loop.call_soon_threadsafe(self._stop.set)
            except RuntimeError:  # loop already closed
                pass
        if self._thread is not None:
            self._thread.join(timeout=15)
            self._thread = None

    def _run(self) -> None:
        self._loop = asyncio.new_event_loop()
        try:
            self._loop.run_until_complete(self._main())
        except BaseException as exc:  # reported by start() or the demo command
            self.error = exc
            log.exception("demo DAQ emulator failed")
        finally:
            self._ready.set()
            self._loop.close()

    async def _main(self) -> None:
        from drivers.emulators.modbus_daq import ModbusDaqEmulator
        from drivers.interface import SampleBlock
        from drivers.scaling import ChannelScaling

        self._stop = asyncio.Event()
        em = self.emulator = ModbusDaqEmulator([], transport="tcp", host=self.host, port=self.port,
                                               scaling=ChannelScaling.from_breaker(self.breaker))
        await em.start()
        self.port = em.port
        self._ready.set()
        items = _HistoryProcess(self.breaker, self.script)
        try:
            sample_index = 0
            while not self._stop.is_set():
                cap = await asyncio.to_thread(items.next)
                if cap is None:
                    break
                em.add_capture(SampleBlock(sample_index, cap.travel, cap.vibration, cap.sample_rate))
                self.queued += 1
                sample_index += int(cap.sample_rate * self.script.interval_s)
                try:
                    await asyncio.wait_for(self._stop.wait(), self.script.interval_s)
                except asyncio.TimeoutError:
                    pass
            while not self._stop.is_set() and em.stats.captures_acknowledged < self.queued:
                try:
                    await asyncio.wait_for(self._stop.wait(), 0.2)
                except asyncio.TimeoutError:
                    pass
            self.done.set()
            await self._stop.wait()
        finally:
            await asyncio.to_thread(items.close)
            await em.stop()
