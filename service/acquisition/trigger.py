"""Operation trigger: finds openings and closings in an endless 2-channel stream and cuts them
into captures with their valid window.

Time is the sample index; there is no clock inside. The detector keeps a fixed-size ring buffer
of the most recent samples (pre-trigger history plus the longest operation), so its memory does
not depend on how long the stream runs. Work per block is vectorised with numpy.

Detection: the latch-release shock (|vibration| ≥ ``shock_threshold_g``) arms a candidate; it
becomes an operation when the smoothed travel moves more than ``motion_fraction`` of the stroke
within ``confirm_s``. A shock without motion is rejected. The direction of travel decides
opening (travel rises from closed) or closing. The valid window runs from the shock to the peak
of the operation's own coordinate: for openings the top of the travel (one cubic across it, or
one per side for a quick or oscillating return), for closings the end of the cam rise, from a
fit of the approach to the settled closed level (``operation_end``). While an opening settles,
its swing about rest starts no operation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drivers.capture import Capture
from drivers.interface import SampleBlock

from .operation_end import closing_end, moving_average, opening_end, settling
from .sample_ring import SampleRing

OPEN, CLOSE = "open", "close"
INCOMPLETE = "incomplete"                 # samples missing (stream gap) or stream ended early
SHORT_PRETRIGGER = "short_pretrigger"     # less than half the pre-trigger time was available
NEXT_OPERATION = "next_operation"         # cut short because the next operation started
END_NOT_REACHED = "end_not_reached"       # travel never reached its end position
VIBRATION_CLIPPED = "vibration_clipped"   # the latch shock hit the accelerometer's full scale
PEAK_FIT_FAILED = "peak_fit_failed"       # window end taken from the smoothed maximum instead


@dataclass(frozen=True)
class TriggerSettings:
    """Trigger and capture settings (times in s, fractions of the stroke).

    Attributes
    ----------
    stroke_rad : float
        Travel between closed and open rest positions [rad].
    shock_threshold_g : float
        Latch-release shock detection level [g].
    motion_fraction : float
        Travel must move this fraction of the stroke to confirm an operation [-].
    pre_trigger_s, post_s : float
        Capture before the shock, and after the end position is reached and settled [s].
    confirm_s : float
        Longest delay from the shock to confirming motion [s].
    max_operation_s : float
        Longest shock-to-end-position time expected [s]; sets the ring buffer size.
    baseline_s : float
        Pre-shock travel used as the start level [s].
    smoothing_s : float
        Moving-average length for travel decisions [s].
    shock_cluster_gap_s : float
        Exceedances closer than this belong to one shock [s].
    end_band_fraction : float
        Travel within this fraction of the stroke from its far end counts as arriving [-].
    settle_s, settle_fraction : float
        Settled when the travel changes less than ``settle_fraction`` of the stroke over ``settle_s``.
    rest_s : float
        At rest after an operation when the travel stays within ``settle_fraction`` of the stroke
        for ``rest_s`` (about one period of a rebound ringing about rest) [s].
    peak_half_window_s : float
        Half width of the opening peak fit [s].
    peak_fit_drop_fraction : float
        Each side of the opening peak fit ends where the travel has fallen this fraction of the
        stroke below the top (or at the half width) [-].
    closing_fit_fraction : float
        The closing end fit uses the last part of the motion, this fraction of the stroke [-].
    rearm_s : float
        Shocks within this time after an operation's end belong to it [s].
    vibration_full_scale_g, travel_full_scale_rad : float
        Sensor ranges [g], [rad]; clipping detection and capture limits.
    """

    stroke_rad: float = 1.0
    shock_threshold_g: float = 50.0
    motion_fraction: float = 0.05
    pre_trigger_s: float = 0.02
    post_s: float = 0.03
    confirm_s: float = 0.04
    max_operation_s: float = 0.15
    baseline_s: float = 0.005
    smoothing_s: float = 0.25e-3
    shock_cluster_gap_s: float = 2e-3
    end_band_fraction: float = 0.1
    settle_s: float = 0.005
    settle_fraction: float = 0.01
    rest_s: float = 0.015
    peak_half_window_s: float = 0.006
    peak_fit_drop_fraction: float = 0.01
    closing_fit_fraction: float = 0.15
    rearm_s: float = 0.005
    vibration_full_scale_g: float = 1000.0
    travel_full_scale_rad: float = np.pi

    def __post_init__(self):
        for name in ("stroke_rad", "shock_threshold_g", "pre_trigger_s", "confirm_s",
                     "max_operation_s", "smoothing_s", "settle_s", "rest_s", "peak_half_window_s"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"trigger setting {name} must be a positive number, got {value}")
        if not 0 < self.motion_fraction < 1:
            raise ValueError(f"motion_fraction must be between 0 and 1, got {self.motion_fraction}")

    @classmethod
    def from_breaker(cls, breaker, **overrides) -> "TriggerSettings":
        """Settings from ``breaker.stroke`` and its ``[acquisition]`` table; keyword overrides win."""
        acq = dict(getattr(breaker, "acquisition", None) or {})
        values = {"stroke_rad": float(breaker.stroke)}
        for key in ("shock_threshold_g", "motion_fraction", "pre_trigger_s", "post_s", "confirm_s",
                    "max_operation_s", "vibration_full_scale_g", "travel_full_scale_rad"):
            if key in acq:
                values[key] = float(acq[key])
        values.update(overrides)
        return cls(**values)

    @property
    def horizon_s(self) -> float:
        """Data needed after a shock before it is judged [s]."""
        return self.max_operation_s + max(self.settle_s, self.rest_s) + self.post_s + self.peak_half_window_s


@dataclass(frozen=True)
class DetectedOperation:
    """One detected operation and its capture.

    Indices are stream sample indices; seconds are ``index / sample_rate`` (from index 0).
    ``window_start_index`` is the latch shock (the fitter refines the onset itself);
    ``window_end_index`` the peak of the operation's coordinate (fractional).
    """

    operation: str
    shock_index: int
    window_start_index: float
    window_end_index: float
    sample_rate: float
    flags: tuple
    capture: Capture

    @property
    def window_start_s(self) -> float:
        return self.window_start_index / self.sample_rate

    @property
    def window_end_s(self) -> float:
        return self.window_end_index / self.sample_rate

    @property
    def capture_window_s(self) -> tuple[float, float]:
        """Valid window [s from the capture's first sample]."""
        first = self.capture.first_sample_index
        return ((self.window_start_index - first) / self.sample_rate,
                (self.window_end_index - first) / self.sample_rate)

    def to_dict(self, origin_index: int = 0) -> dict:
        """JSON-able summary; times in s from sample ``origin_index``."""
        fs = self.sample_rate
        cap = self.capture
        out = {"operation": self.operation,
               "t_start_s": (self.window_start_index - origin_index) / fs,
               "t_end_s": (self.window_end_index - origin_index) / fs,
               "flags": list(self.flags),
               "shock_index": int(self.shock_index),
               "capture_start_s": (cap.first_sample_index - origin_index) / fs,
               "capture_end_s": (cap.first_sample_index + cap.travel.size - origin_index) / fs}
        if cap.meta.get("command_source"):  # an analyser record: the command is a coil's rise
            out["command"] = cap.meta["command_source"]
        if cap.meta.get("motion_s") is not None:  # where the travel leaves its rest by 2 % of the stroke
            out["motion_start_s"] = (cap.first_sample_index - origin_index) / fs + float(cap.meta["motion_s"])
        return out


class TriggerDetector:
    """Chunk-by-chunk operation detector with a bounded pre-trigger ring buffer.

    ``feed(block)`` returns the operations completed by that block; ``flush()`` those still
    pending at the end of the stream. Blocks must come in index order; a jump forward is a gap.
    """

    def __init__(self, settings: TriggerSettings, sample_rate: float):
        if not (np.isfinite(sample_rate) and sample_rate > 0):
            raise ValueError(f"sample rate must be a positive number of Hz, got {sample_rate}")
        self.settings = settings
        self.fs = float(sample_rate)
        n = self._n
        self.pre_n = n(settings.pre_trigger_s)
        self.horizon_n = n(settings.horizon_s)
        self.chunk_n = max(1024, self.horizon_n // 4)  # largest piece processed at once
        self.scan_n = 4096  # small blocks are searched together: less overhead per sample
        self.ring = SampleRing(self.pre_n + self.horizon_n + self.chunk_n + self.scan_n + 16)
        self._expected: int | None = None
        self._scan = 0
        self._pending: int | None = None
        self._gaps: list[tuple[int, int]] = []  # (first missing index, count) still in the ring
        self._settling: tuple | None = None  # last opening's (settled index, rest, swing)

    def _n(self, seconds: float) -> int:
        return int(round(seconds * self.fs))

    @property
    def buffer_samples(self) -> int:
        """Samples the detector holds: fixed by the settings, not by the stream length."""
        return self.ring.capacity

    # -- streaming ----------------------------------------------------------------------------

    def feed(self, block: SampleBlock) -> list[DetectedOperation]:
        """Process one block; returns operations whose captures are now complete."""
        if abs(block.sample_rate - self.fs) > 1e-6 * self.fs:
            raise ValueError(f"block sampled at {block.sample_rate} Hz, detector set for {self.fs} Hz")
        out: list[DetectedOperation] = []
        first = int(block.first_sample_index)
        if self._expected is None or first < self._expected:
            # Start, or a counter that went back (DAQ restart): nothing can be stitched across.
            if self._expected is not None:
                out += self.flush()
            self.ring.reset(first)
            self._scan, self._pending, self._gaps, self._settling = first, None, [], None
        elif first > self._expected:
            self._gaps.append((self._expected, first - self._expected))
            out += self._skip(first - self._expected)
        travel = np.asarray(block.travel, dtype=float)
        vibration = np.asarray(block.vibration, dtype=float)
        for i in range(0, travel.size, self.chunk_n):
            self.ring.append(travel[i:i + self.chunk_n], vibration[i:i + self.chunk_n])
            if self._due():
                out += self._process(final=False)
        self._expected = first + travel.size
        self._gaps = [g for g in self._gaps if g[0] + g[1] > self.ring.start]
        return out

    def _due(self) -> bool:
        if self._pending is not None:
            return self.ring.end >= self._pending + self.horizon_n
        return self.ring.end - self._scan >= self.scan_n

    def _skip(self, count: int) -> list[DetectedOperation]:
        """Account for ``count`` lost samples. A pending candidate is judged once its horizon
        is covered (the lost part marked invalid); beyond that the ring jumps at once."""
        out = []
        while count > 0:
            m = count if self._pending is None else min(count, self.chunk_n)
            self.ring.fill_gap(m)
            count -= m
            out += self._process(final=False)
        return out

    def flush(self, *, record: bool = False) -> list[DetectedOperation]:
        """Judge what is pending with the data there is (end of stream).

        ``record``: the data was one whole recording (a file, a DAQ-triggered capture), whose
        end is the recorder's choice, not lost samples: a capture window that runs past it is
        cut there without the ``incomplete`` flag, as long as the operation itself ended inside.
        """
        if self._expected is None:
            return []
        out = self._process(final=True, record=record)
        self._pending = None
        self._scan = self.ring.end
        return out

    def _process(self, *, final: bool, record: bool = False) -> list[DetectedOperation]:
        out = []
        thr = self.settings.shock_threshold_g
        while True:
            if self._pending is None:
                hit = self.ring.first_exceedance(self._scan, thr)
                if hit is None:
                    self._scan = self.ring.end
                    return out
                self._pending = self._scan = hit
            if not final and self.ring.end < self._pending + self.horizon_n:
                return out  # wait for the whole operation
            detected, resume = self._judge(self._pending, final=final, record=record)
            if detected is not None:
                out.append(detected)
            self._pending, self._scan = None, max(resume, self._pending + 1)

    # -- judging one candidate shock ------------------------------------------------------------

    def _judge(self, shock: int, *, final: bool, record: bool = False):
        """Decide whether the shock at stream index ``shock`` starts an operation.

        Returns (DetectedOperation or None, stream index to resume the shock search from).
        """
        s = self.settings
        n = self._n
        seg0, T, V, M = self.ring.get(shock - self.pre_n, shock + self.horizon_n)
        k = shock - seg0
        S = moving_average(T, max(1, n(s.smoothing_s)))
        thr_motion = s.motion_fraction * s.stroke_rad
        before = slice(max(0, k - n(s.baseline_s)), k)
        baseline = float(np.median(T[before][M[before]])) if M[before].any() else float(T[k])
        threshold = thr_motion
        if self._settling is not None and shock < self._settling[0]:
            # The previous opening is still settling: its swing about rest is no operation.
            _, baseline, swing = self._settling
            threshold = thr_motion + swing
        dev = S[k:k + n(s.confirm_s)] - baseline
        moved = np.flatnonzero(np.abs(dev) > threshold)
        hits = np.flatnonzero((np.abs(V[k:]) >= s.shock_threshold_g) & M[k:]) + k
        if moved.size == 0:  # a lone shock: skip past its ringing
            return None, seg0 + _cluster_end(hits, n(s.shock_cluster_gap_s))
        c = k + int(moved[0])
        direction = 1.0 if dev[moved[0]] > 0 else -1.0
        operation = OPEN if direction > 0 else CLOSE
        # The latch shock is the last shock cluster that starts before motion is confirmed.
        pre = hits[hits < c]
        if pre.size == 0:  # already moving at the shock: this shock did not start it
            return None, seg0 + _cluster_end(hits, n(s.shock_cluster_gap_s))
        breaks = np.flatnonzero(np.diff(pre) > n(s.shock_cluster_gap_s))
        k = int(pre[breaks[-1] + 1]) if breaks.size else int(pre[0])
        flags = []
        arrived = np.flatnonzero(direction * (S[c:] - baseline) >= (1 - s.end_band_fraction) * s.stroke_rad)
        if arrived.size == 0:
            flags.append(END_NOT_REACHED)
            end = float(c + np.argmax(direction * S[c:])) if S.size > c else float(c)
        else:
            r = c + int(arrived[0])
            if direction > 0:
                end, ok = opening_end(T, M, S, r, s, self.fs)
            else:
                end, ok = closing_end(T, M, S, r, s, self.fs)
            if not ok:
                flags.append(PEAK_FIT_FAILED)
        stop, cut, settle = self._capture_stop(S, int(np.ceil(end)), baseline, direction)
        if cut:
            flags.append(NEXT_OPERATION)
        if operation == OPEN:  # shocks while it settles are judged against its swing
            self._settling = (seg0 + settle.settled, settle.rest, settle.swing)
        start = max(0, k - self.pre_n)
        if k < self.pre_n // 2:  # a little less than asked is normal for recorded files
            flags.append(SHORT_PRETRIGGER)
        # `incomplete` means samples are missing: the data ended before the operation did, a
        # live stream ended inside the capture window, or (below) a gap lies inside it.
        if (final and arrived.size == 0) or (stop > T.size and not record):
            flags.append(INCOMPLETE)
        stop = min(stop, T.size)
        if not M[start:stop].all() and INCOMPLETE not in flags:
            flags.append(INCOMPLETE)
        if np.any(np.abs(V[k:k + n(0.005)]) >= 0.999 * s.vibration_full_scale_g):
            flags.append(VIBRATION_CLIPPED)
        capture = self._capture(seg0 + start, T[start:stop], V[start:stop], M[start:stop],
                                operation, seg0 + k, seg0 + end, tuple(flags))
        detected = DetectedOperation(operation, seg0 + k, float(seg0 + k), float(seg0 + end),
                                     self.fs, tuple(flags), capture)
        return detected, seg0 + int(np.ceil(end)) + n(s.rearm_s)

    def _capture_stop(self, S, end: int, baseline: float, direction: float):
        """Segment index one past the capture's last sample, whether the next operation cut it,
        and how the travel settled (``operation_end.Settling``)."""
        s = self.settings
        n = self._n
        thr_motion = s.motion_fraction * s.stroke_rad
        end = min(max(end, 0), S.size - 1)
        level = float(S[end])
        # The settling swings about the end position by at most the overtravel: twice the
        # distance from the end level to the nominal rest, plus the motion threshold.
        reach = 2.0 * abs(level - (baseline + direction * s.stroke_rad)) + thr_motion
        st = settling(S, end, reach, s, self.fs, limit=S.size - n(s.post_s))
        stop = (st.settled if st.found else end) + n(s.post_s)
        # A new operation: leaving the settling's reach before it settles, or the rest level after.
        i0 = end + n(s.rearm_s)
        idx = np.arange(i0, min(stop, S.size))
        far = np.where(idx < st.settled, np.abs(S[i0:i0 + idx.size] - level) > reach,
                       np.abs(S[i0:i0 + idx.size] - st.rest) > thr_motion)
        away = np.flatnonzero(far)
        if away.size:  # the next operation has started: end where the travel left its rest level
            leave = i0 + int(away[0])
            ref = st.rest if st.found and leave >= st.settled else level
            quiet = np.flatnonzero(np.abs(S[end:leave] - ref) < 0.1 * thr_motion)
            return end + (int(quiet[-1]) + 1 if quiet.size else leave - end), True, st
        return stop, False, st

    def _capture(self, first, T, V, M, operation, shock, end, flags) -> Capture:
        travel = T.copy()
        vibration = V.copy()
        if not M.all():  # lost samples: interpolated travel, zero vibration, and flagged
            good = np.flatnonzero(M)
            if good.size:
                travel[~M] = np.interp(np.flatnonzero(~M), good, T[good])
            vibration[~M] = 0.0
        s = self.settings
        gaps = [(int(g0), int(cnt)) for g0, cnt in self._gaps
                if g0 < first + T.size and g0 + cnt > first]
        meta = {"operation": operation, "shock_index": int(shock),
                "window_start_s": (shock - first) / self.fs, "window_end_s": (end - first) / self.fs,
                "gaps": gaps}
        return Capture(travel=travel, sample_rate=self.fs, vibration=vibration,
                       source=f"trigger-{operation}", flags=flags, first_sample_index=int(first),
                       travel_limits=(0.0, float(s.travel_full_scale_rad)),
                       vibration_limits=(-float(s.vibration_full_scale_g), float(s.vibration_full_scale_g)),
                       meta=meta)


# -- numerical helpers ---------------------------------------------------------------------------

def _cluster_end(hits: np.ndarray, gap: int) -> int:
    """Index one past the first cluster of exceedances (``hits`` sorted)."""
    if hits.size == 0:
        return 0
    breaks = np.flatnonzero(np.diff(hits) > gap)
    return int(hits[breaks[0]] if breaks.size else hits[-1]) + 1
