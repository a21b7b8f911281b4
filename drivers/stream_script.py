"""Long scripted 2-channel streams with known truth: idle time, operations, lone shocks, noise
bursts and dropped sample ranges, generated lazily in sample blocks.

The travel channel is continuous: the breaker rests open after an opening and closed after a
closing, and each operation starts from wherever the previous one left the shaft. Operations
come from the project's own models (``synthetic.operation_travel``); the vibration channel
carries the latch-release shock 0.4 ms before motion, the buffer engagement (openings) and the
end-of-travel impact, like ``synthetic.vibration_signature``.

Noise is drawn per fixed chunk of samples from ``(seed, chunk)``, so a stream is the same
whatever block size it is read in, and memory stays bounded however long it runs.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from drivers.interface import SampleBlock

from service.mechanics.breaker import Breaker
from drivers.capture import Capture
from .synthetic import SHOCK_LEAD_S, operation_travel

CHUNK = 65_536                 # samples generated at once; noise is seeded per chunk
OPEN_TEMPLATE_S = 0.3          # simulated opening length; the model has settled by then [s]
BURST_TAU_S = 0.6e-3           # decay time of a vibration burst [s]
BURST_LENGTH_S = 12 * BURST_TAU_S
FULL_SCALE_G = 1000.0          # accelerometer clips here [g]
TRAVEL_FULL_SCALE_RAD = np.pi  # 0–180° resistive sensor [rad]
LATCH_FREQ_HZ, BUFFER_FREQ_HZ, END_FREQ_HZ = 2500.0, 2200.0, 1800.0
REST_FREQ_HZ = 2000.0
# How an opening returns from its overtravel to the open rest position: the model's own slow
# return, a critically damped one back at rest within CRITICAL_RETURN_S, or an oscillating one
# whose rebound swings past rest (damping ratio and frequency below).
RETURN_SHAPES = ("model", "critical", "oscillating")
CRITICAL_RETURN_S = 5e-3
OSCILLATING_ZETA, OSCILLATING_HZ = 0.15, 60.0


@dataclass(frozen=True)
class ScriptedOperation:
    """One operation in a script.

    ``t_s`` is the onset of motion [s from the first sample]; when None the motion starts
    ``delay_s`` after the previous operation's valid window ends (a CO sequence). ``params``
    defaults to the breaker's design parameters; ``shock_g`` above 1000 g clips.
    """

    operation: str
    t_s: float | None = None
    delay_s: float = 0.03
    params: Mapping[str, float] | None = None
    shock_g: float = 420.0


@dataclass(frozen=True)
class LoneShock:
    """A vibration shock with no motion (a door slam, a neighbouring breaker) [s, g, Hz]."""

    t_s: float
    peak_g: float = 300.0
    freq_hz: float = 2500.0


@dataclass(frozen=True)
class NoiseBurst:
    """Broadband interference on both channels [s, s, g, rad]."""

    t_s: float
    duration_s: float = 0.05
    vibration_sd_g: float = 60.0
    travel_sd_rad: float = 0.004


@dataclass(frozen=True)
class Gap:
    """Samples the DAQ link lost: they are never delivered [s, s]."""

    t_s: float
    duration_s: float


@dataclass(frozen=True)
class OperationTruth:
    """What the script knows about one operation (times in s from sample index 0).

    ``t_end_s`` is the valid window's end: the peak of the operation's own coordinate.
    ``capture_start_s``/``capture_end_s`` are the nominal capture bounds (20 ms before the
    shock, 30 ms after the end). ``incomplete``: a gap falls inside the capture bounds.
    """

    operation: str
    t_shock_s: float
    t_motion_s: float
    t_end_s: float
    shock_index: int
    capture_start_s: float
    capture_end_s: float
    incomplete: bool
    clipped: bool
    params: dict = field(default_factory=dict)


@dataclass(frozen=True)
class _Placed:
    operation: str
    motion_index: int
    template: np.ndarray     # travel [rad] from the motion onset, already blended to its start level
    final: float             # rest level after the operation [rad]
    peak_samples: float      # valid-window end after motion onset [samples]
    events: tuple            # (sample index [float], peak g, freq Hz)
    params: dict


class ScriptedStream:
    """A long stream of travel [rad] and vibration [g] with ground truth.

    Parameters
    ----------
    breaker : Breaker
    duration_s : float
        Stream length [s].
    seed : int
    operations : sequence of ScriptedOperation, optional
        Default: alternating openings and closings every ``spacing_s`` from 0.3 s.
    shocks, bursts, gaps : sequences of LoneShock, NoiseBurst, Gap
    fs : float
        Sample rate [Hz].
    noise_rad, noise_g : float
        Sensor noise standard deviations [rad], [g].
    bits : int or None
        Quantise both channels to 16-bit codes like the DAQ (travel over 0..π, vibration ±1000 g).
    initial : {"closed", "open"}
    param_spread : float
        Relative random spread of each operation's parameters around the design values.
    first_index : int
        Sample index of the first sample.
    return_shape : {"model", "critical", "oscillating"}
        How openings return from their overtravel to rest (see ``opening_return``); the
        returning shaft hits its rest stop (critical) or swings through rest (oscillating)
        with a vibration burst, so the settling carries a shock.
    """

    def __init__(self, breaker: Breaker, *, duration_s: float, seed: int = 1,
                 operations: Sequence[ScriptedOperation] | None = None,
                 shocks: Sequence[LoneShock] = (), bursts: Sequence[NoiseBurst] = (),
                 gaps: Sequence[Gap] = (), fs: float = 128_000.0, noise_rad: float = 0.0015,
                 noise_g: float = 0.6, bits: int | None = 16, initial: str = "closed",
                 spacing_s: float = 1.0, param_spread: float = 0.0, first_index: int = 0,
                 pre_s: float = 0.02, post_s: float = 0.03, return_shape: str = "model"):
        if not duration_s > 0 or not fs > 0:
            raise ValueError("a scripted stream needs a positive duration [s] and sample rate [Hz]")
        if initial not in ("closed", "open"):
            raise ValueError(f"initial position must be 'closed' or 'open', got {initial!r}")
        if return_shape not in RETURN_SHAPES:
            raise ValueError(f"return shape must be one of {', '.join(RETURN_SHAPES)}, got {return_shape!r}")
        self.return_shape = return_shape
        self.breaker, self.fs, self.seed = breaker, float(fs), int(seed)
        self.n_samples = int(round(duration_s * fs))
        self.first_index = int(first_index)
        self.noise_rad, self.noise_g, self.bits = noise_rad, noise_g, bits
        if operations is None:
            operations = _alternating(duration_s, spacing_s, initial)
        self._templates: dict = {}
        self._rng_params = np.random.default_rng([self.seed, 7])
        self._param_spread = param_spread
        self._initial_level = 0.0 if initial == "closed" else self._open_rest_level()
        self._ops = self._place(operations, initial)
        self._motion = [op.motion_index for op in self._ops]
        self._events = sorted(
            [ev for op in self._ops for ev in op.events]
            + [(s.t_s * fs, s.peak_g, s.freq_hz) for s in shocks])
        self._event_starts = [ev[0] for ev in self._events]
        self._bursts = sorted((int(round(b.t_s * fs)), int(round((b.t_s + b.duration_s) * fs)),
                               b.vibration_sd_g, b.travel_sd_rad) for b in bursts)
        self._gaps = sorted((int(round(g.t_s * fs)), int(round((g.t_s + g.duration_s) * fs)))
                            for g in gaps)
        self.truth = [self._truth(op, pre_s, post_s) for op in self._ops]
        self._cache: dict = {}

    # -- script -------------------------------------------------------------------------------

    def _params(self, operation, given):
        if given is not None:
            return dict(given)
        design = self.breaker.design_parameters()
        keys = ("AO", "BO", "DO", "EO") if operation == "open" else ("AC", "BC", "CC", "DC")
        p = {k: design[k] for k in keys}
        if self._param_spread:
            for k in ("AO", "BO", "DO", "EO") if operation == "open" else ("AC", "CC"):
                p[k] *= 1.0 + self._param_spread * self._rng_params.uniform(-1.0, 1.0)
        return p

    def _template(self, operation, params):
        """Noise-free travel from motion onset [rad], the valid-window end [s], the buffer
        engagement [s] and the instant the return reaches rest [s] (NaN: model return); cached."""
        key = (operation, tuple(sorted(params.items())))
        if key not in self._templates:
            t = np.arange(int(OPEN_TEMPLATE_S * self.fs)) / self.fs
            travel, t_peak, tr = operation_travel(self.breaker, operation, params, t)
            if not np.isfinite(t_peak):
                raise ValueError(f"the scripted {operation} never reaches its end position")
            if operation == "close":
                # Past the end of the cam rise the breaker is latched closed: hold the level.
                k = int(np.floor(t_peak * self.fs)) + 1
                travel = travel[:k]
            events = tr.events.get("buffer_engaged", np.nan) if operation == "open" else np.nan
            t_rest = np.nan
            if operation == "open" and self.return_shape != "model":
                travel, t_rest = opening_return(travel, t_peak, self.fs, self.return_shape)
            self._templates[key] = (travel, float(t_peak), float(events), float(t_rest))
        return self._templates[key]

    def _open_rest_level(self):
        travel = self._template("open", self._params("open", None))[0]
        return float(travel[-1])

    def _place(self, operations, initial) -> list[_Placed]:
        placed: list[_Placed] = []
        position, level = initial, self._initial_level
        for spec in operations:
            if spec.operation not in ("open", "close"):
                raise ValueError(f"operation must be 'open' or 'close', got {spec.operation!r}")
            wanted = "closed" if spec.operation == "open" else "open"
            if position != wanted:
                raise ValueError(f"cannot {spec.operation} a breaker that is already {position}")
            params = self._params(spec.operation, spec.params)
            model, t_peak, t_buffer, t_rest = self._template(spec.operation, params)
            if spec.t_s is None:
                if not placed:
                    raise ValueError("the first scripted operation needs a time t_s")
                prev = placed[-1]
                m = int(round(prev.motion_index + prev.peak_samples + spec.delay_s * self.fs))
            else:
                m = int(round(spec.t_s * self.fs))
            if placed:
                prev = placed[-1]
                if m <= prev.motion_index:
                    raise ValueError("scripted operations must be in time order")
                level = _level_at(prev, m - prev.motion_index)
            template = _blend(model, level)
            events = [((m - SHOCK_LEAD_S * self.fs), spec.shock_g, LATCH_FREQ_HZ),
                      (m + t_peak * self.fs, 0.3 * 420.0, END_FREQ_HZ)]
            if np.isfinite(t_buffer):
                events.append((m + t_buffer * self.fs, 0.6 * 420.0, BUFFER_FREQ_HZ))
            if np.isfinite(t_rest):
                events.append((m + t_rest * self.fs, 0.3 * 420.0, REST_FREQ_HZ))
            placed.append(_Placed(spec.operation, m, template, float(template[-1]),
                                  t_peak * self.fs, tuple(events), params))
            position = "open" if spec.operation == "open" else "closed"
        if placed and placed[-1].motion_index >= self.n_samples:
            raise ValueError("a scripted operation starts after the end of the stream")
        return placed

    def _truth(self, op: _Placed, pre_s, post_s) -> OperationTruth:
        fs = self.fs
        shock = op.events[0][0]
        start, end = shock / fs - pre_s, (op.motion_index + op.peak_samples) / fs + post_s
        incomplete = any(g0 < end * fs and g1 > start * fs for g0, g1 in self._gaps)
        return OperationTruth(op.operation, shock / fs, op.motion_index / fs,
                              (op.motion_index + op.peak_samples) / fs, int(np.ceil(shock)),
                              start, end, incomplete, op.events[0][1] > FULL_SCALE_G, op.params)

    # -- samples ------------------------------------------------------------------------------

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.fs

    def _chunk(self, k: int):
        if k not in self._cache:
            if len(self._cache) >= 2:  # keep the current and the previous chunk only
                self._cache.pop(min(self._cache))
            self._cache[k] = self._generate(k * CHUNK, min((k + 1) * CHUNK, self.n_samples), k)
        return self._cache[k]

    def _generate(self, i0: int, i1: int, k: int):
        rng = np.random.default_rng([self.seed, k])
        n = i1 - i0
        travel = self._travel_level(i0, i1) + rng.normal(0.0, self.noise_rad, n)
        vib = rng.normal(0.0, self.noise_g, n)
        idx = np.arange(i0, i1, dtype=float)
        lo = bisect.bisect_left(self._event_starts, i0 - BURST_LENGTH_S * self.fs)
        hi = bisect.bisect_left(self._event_starts, i1)
        for t0, peak, freq in self._events[lo:hi]:
            a, b = max(int(np.ceil(t0)), i0), min(int(np.ceil(t0 + BURST_LENGTH_S * self.fs)), i1)
            if b > a:
                dt = (idx[a - i0:b - i0] - t0) / self.fs
                vib[a - i0:b - i0] += peak * np.exp(-dt / BURST_TAU_S) * np.sin(2 * np.pi * freq * dt)
        for b0, b1, sd_g, sd_rad in self._bursts:
            a, b = max(b0, i0), min(b1, i1)
            if b > a:
                vib[a - i0:b - i0] += rng.normal(0.0, sd_g, b - a)
                travel[a - i0:b - i0] += rng.normal(0.0, sd_rad, b - a)
        vib = np.clip(vib, -FULL_SCALE_G, FULL_SCALE_G)
        if self.bits:
            lsb_t = TRAVEL_FULL_SCALE_RAD / (2**self.bits - 1)
            lsb_v = FULL_SCALE_G / (2 ** (self.bits - 1) - 1)
            travel = np.round(travel / lsb_t) * lsb_t
            vib = np.round(vib / lsb_v) * lsb_v
        return travel, vib

    def _travel_level(self, i0: int, i1: int) -> np.ndarray:
        """Noise-free travel [rad] on samples [i0, i1)."""
        out = np.empty(i1 - i0)
        j = bisect.bisect_right(self._motion, i0) - 1  # operation active at i0 (-1: none yet)
        pos = i0
        while pos < i1:
            nxt = self._motion[j + 1] if j + 1 < len(self._ops) else self.n_samples
            stop = min(max(nxt, pos), i1)
            if j < 0:
                out[pos - i0:stop - i0] = self._initial_level
            else:
                op = self._ops[j]
                rel = np.arange(pos - op.motion_index, stop - op.motion_index)
                inside = rel < op.template.size
                out[pos - i0:stop - i0] = np.where(
                    inside, op.template[np.minimum(rel, op.template.size - 1)], op.final)
            pos, j = stop, j + 1
        return out

    def samples(self, i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
        """Travel [rad] and vibration [g] of stream samples [i0, i1) (gaps not removed)."""
        i0, i1 = max(i0, 0), min(i1, self.n_samples)
        parts_t, parts_v = [], []
        pos = i0
        while pos < i1:
            k = pos // CHUNK
            tr, vb = self._chunk(k)
            stop = min(i1, (k + 1) * CHUNK)
            parts_t.append(tr[pos - k * CHUNK:stop - k * CHUNK])
            parts_v.append(vb[pos - k * CHUNK:stop - k * CHUNK])
            pos = stop
        if not parts_t:
            return np.empty(0), np.empty(0)
        return np.concatenate(parts_t), np.concatenate(parts_v)

    def blocks(self, n: int = 4096) -> Iterator[SampleBlock]:
        """Sample blocks of at most ``n`` samples, lazily; dropped ranges are skipped, so the
        block after a gap starts with a jump in ``first_sample_index``."""
        if n <= 0:
            raise ValueError("block size must be a positive number of samples")
        pos = 0
        gaps = [(g0, g1) for g0, g1 in self._gaps if g1 > g0]
        while pos < self.n_samples:
            for g0, g1 in gaps:
                if g0 <= pos < g1:
                    pos = g1
            if pos >= self.n_samples:
                break
            stop = min(pos + n, self.n_samples)
            for g0, _ in gaps:
                if pos < g0 < stop:
                    stop = g0
            travel, vib = self.samples(pos, stop)
            yield SampleBlock(self.first_index + pos, travel, vib, self.fs)
            pos = stop

    def to_capture(self, source: str = "scripted-stream") -> Capture:
        """The whole stream as one Capture (short streams only; gaps are not represented)."""
        if self._gaps:
            raise ValueError("a stream with gaps cannot be one uniform capture")
        travel, vib = self.samples(0, self.n_samples)
        return Capture(travel=travel, sample_rate=self.fs, vibration=vib, source=source,
                       first_sample_index=self.first_index,
                       travel_limits=(0.0, TRAVEL_FULL_SCALE_RAD),
                       vibration_limits=(-FULL_SCALE_G, FULL_SCALE_G))


def opening_return(travel: np.ndarray, t_peak: float, fs: float, shape: str):
    """Replace an opening's return from its overtravel by ``shape``.

    ``travel`` [rad] is sampled at ``fs`` [Hz] from the motion onset and ends at the open rest
    level; ``t_peak`` [s] is its maximum. Before the peak nothing changes; after it the travel
    leaves the peak with zero speed and goes back to the rest level:

    - ``critical``: (1 + ωτ)·e^(−ωτ), ω = 6 / CRITICAL_RETURN_S (within 2 % of rest by then);
    - ``oscillating``: a damped swing (ζ, f) that passes the rest level and rings about it.

    Returns the new travel and the time [s] the return first reaches rest (the rest-stop
    impact, or the first pass through rest).
    """
    t = np.arange(travel.size) / fs
    after = t > t_peak
    k = int(np.argmax(after))
    rest = float(travel[-1])
    top = float(np.max(travel[max(k - 2, 0):k + 1]))
    tau = t[after] - t_peak
    if shape == "critical":
        w = 6.0 / CRITICAL_RETURN_S
        ret = (1.0 + w * tau) * np.exp(-w * tau)
        t_rest = CRITICAL_RETURN_S
    elif shape == "oscillating":
        wn = 2 * np.pi * OSCILLATING_HZ
        wd = wn * np.sqrt(1 - OSCILLATING_ZETA**2)
        decay = OSCILLATING_ZETA * wn
        ret = np.exp(-decay * tau) * (np.cos(wd * tau) + decay / wd * np.sin(wd * tau))
        t_rest = float(np.arctan2(-wd, decay) % np.pi) / wd  # first zero of the swing
    else:
        raise ValueError(f"return shape must be one of {', '.join(RETURN_SHAPES[1:])}, got {shape!r}")
    out = travel.copy()
    out[after] = rest + (top - rest) * ret
    return out, t_peak + t_rest


def _blend(model: np.ndarray, start_level: float) -> np.ndarray:
    """Shift a model travel so it starts at ``start_level`` and ends where the model ends: the
    offset fades with the operation's progress, so the level stays continuous."""
    span = model[-1] - model[0]
    progress = np.clip((model - model[0]) / span, 0.0, 1.0) if span else np.ones_like(model)
    return model + (start_level - model[0]) * (1.0 - progress)


def _level_at(op: _Placed, rel: int) -> float:
    return float(op.template[rel]) if rel < op.template.size else op.final


def _alternating(duration_s, spacing_s, initial) -> list[ScriptedOperation]:
    ops, t = [], 0.3
    kind = "open" if initial == "closed" else "close"
    while t + 0.3 < duration_s:
        ops.append(ScriptedOperation(kind, t))
        kind = "close" if kind == "open" else "open"
        t += spacing_s
    return ops


def acceptance_script(breaker: Breaker, seed: int = 1, **kwargs) -> ScriptedStream:
    """The issue's 60 s acceptance stream: 12 operations including an O–0.3 s–CO sequence,
    3 lone vibration shocks, a noise burst and a clipped (±1000 g) latch shock. Keyword
    arguments go to ``ScriptedStream`` (e.g. ``return_shape``)."""
    O, C = "open", "close"
    ops = [
        ScriptedOperation(O, 2.0), ScriptedOperation(C, 6.5), ScriptedOperation(O, 11.0),
        ScriptedOperation(C, 15.5),
        ScriptedOperation(O, 20.0), ScriptedOperation(C, 20.3), ScriptedOperation(O, None, 0.03),
        ScriptedOperation(C, 26.0),
        ScriptedOperation(O, 31.0, shock_g=2500.0),  # clips at full scale
        ScriptedOperation(C, 36.0), ScriptedOperation(O, 42.0), ScriptedOperation(C, 48.0),
    ]
    shocks = [LoneShock(4.0, 250.0), LoneShock(13.2, 600.0, 1900.0), LoneShock(33.5, 180.0)]
    bursts = [NoiseBurst(24.0, 0.06)]
    kwargs.setdefault("param_spread", 0.03)
    return ScriptedStream(breaker, duration_s=60.0, seed=seed, operations=ops, shocks=shocks,
                          bursts=bursts, **kwargs)
