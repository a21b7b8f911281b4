"""The valid fitting window of a capture, its noise floor, and the decimated fitting grid.

Every check an engineer would make before trusting a fit lives here: NaN, too short, no motion,
a saturated travel channel, a wrong-direction operation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from drivers.capture import Capture
from drivers.masked import describe, overlapping
from ..mechanics.breaker import Breaker
from ..mechanics.coordinates import operation_coordinate


class FitError(ValueError):
    """A capture cannot be fitted: the message says why, for an engineer."""


@dataclass(frozen=True)
class FitWindow:
    """Measured data of one operation, ready for fitting.

    Attributes
    ----------
    t : ndarray
        Sample times from the window start (the latch shock) [s].
    y : ndarray
        Operation coordinate at those samples [rad].
    t_start : float
        Window start in capture time [s from the first sample].
    t_end : float
        Window end (peak of the operation coordinate) [s from the first sample].
    noise_rad : float
        Travel noise standard deviation from the idle pre-trigger samples [rad].
    noise_source : str
        ``pre-trigger`` or ``differences`` (no idle part: estimated from sample differences).
    shock_found : bool
        Whether the start came from the vibration shock (else the first sample).
    sample_rate : float
        [Hz]
    tau_range : tuple of float or None
        Onset-delay search range [s] when the start is a coil command (``command_source``);
        None: the estimator's latch-shock range.
    command_source : str
        ``latch shock`` (vibration), ``coil C4/...`` (a coil current's rise) or ``first sample``.
    zero_rad : float
        The operation coordinate's level at rest before the motion (the idle samples' mean),
        taken off ``y`` [rad]; 0 when there are too few idle samples to measure it.
    """

    t: np.ndarray
    y: np.ndarray
    t_start: float
    t_end: float
    noise_rad: float
    noise_source: str
    shock_found: bool
    sample_rate: float
    tau_range: tuple | None = None
    command_source: str = "latch shock"
    zero_rad: float = 0.0


@dataclass(frozen=True)
class Grid:
    """Block-averaged samples: the anti-aliased fitting grid.

    ``t`` are block centres [s], ``y`` block means [rad], ``count`` samples per block and
    ``spread`` the mean of (t - centre)^2 within each block [s^2] (for the curvature term).
    """

    t: np.ndarray
    y: np.ndarray
    count: np.ndarray
    spread: np.ndarray

    @property
    def weight(self) -> np.ndarray:
        """sqrt(count): makes block residuals carry the per-sample noise variance."""
        return np.sqrt(self.count)


def decimate(t, y, block: int) -> Grid:
    """Average consecutive blocks of ``block`` samples (a boxcar anti-alias filter)."""
    n = t.size
    if block <= 1:
        return Grid(t.copy(), y.copy(), np.ones(n), np.zeros(n))
    edges = np.arange(0, n, block)
    count = np.diff(np.append(edges, n)).astype(float)
    tc = np.add.reduceat(t, edges) / count
    yc = np.add.reduceat(y, edges) / count
    dt = t[1] - t[0] if n > 1 else 0.0
    spread = dt * dt * (count * count - 1.0) / 12.0
    return Grid(tc, yc, count, spread)


# Idle samples needed to take the noise from the pre-trigger: the standard deviation of n
# samples is then known to ±1/sqrt(2(n-1)) = ±10 % (n = 50), at any sample rate.
MIN_IDLE = 50
# Rates the estimator's block sizes are stated at; other rates keep the same block duration.
REFERENCE_RATE_HZ = 128_000.0
# The model starts from rest at the onset, so it reaches the 2 %-of-stroke departure a few ms
# later (sqrt(2·0.02/BO) = 2.8 ms for the reference BO); 15 ms covers BO down to 180 s^-2.
# After a coil command the onset delay is searched in [departure − this, departure + 1 ms].
ONSET_BEFORE_DEPARTURE_S = 15e-3


def block_samples(block_at_reference: int, sample_rate: float) -> int:
    """Samples per fitting-grid block at ``sample_rate`` [Hz] for a block stated at 128 kS/s:
    the same block duration (so the same anti-alias bandwidth), at least one sample."""
    return max(1, int(round(block_at_reference * sample_rate / REFERENCE_RATE_HZ)))


def prepare_window(capture: Capture, breaker: Breaker, operation: str, *, take_zero: bool = True) -> FitWindow:
    """Find the valid interval of one operation in a capture.

    The start is the latch-release shock in the vibration channel (the first sample when there
    is no vibration channel); the end is the peak of the operation's own coordinate, fitted
    rather than taken as the argmax of noisy samples.
    """
    fs = float(capture.sample_rate)
    travel = np.asarray(capture.travel, dtype=float)
    src = capture.source or "capture"
    if not np.isfinite(fs) or fs <= 0:
        raise FitError(f"{src}: invalid sample rate {fs}")
    if travel.size < 0.01 * fs or travel.size < 64:
        raise FitError(f"{src}: capture too short ({travel.size} samples, {travel.size / fs * 1e3:.1f} ms)")
    if not np.all(np.isfinite(travel)):
        raise FitError(f"{src}: the travel channel contains NaN or infinite samples")
    stroke = breaker.stroke
    y = operation_coordinate(travel, operation, stroke)
    span = float(np.ptp(travel))
    if span < 0.1 * stroke:
        raise FitError(f"{src}: no motion: the travel moves only {span:.4f} rad "
                       f"(stroke {stroke:.3f} rad); is this an operation?")
    if span > 3.0 * stroke + 0.5:
        raise FitError(f"{src}: the travel spans {span:.2f} rad, far more than the {stroke:.2f} rad "
                       "stroke: check the channel's unit (rad expected, not degrees)")
    smooth = _moving_average(y, max(int(fs * 0.5e-3), 1))
    # Direction: the operation's coordinate must rise.
    head = smooth[: max(int(0.05 * y.size), 8)].mean()
    tail = smooth[-max(int(0.05 * y.size), 8):].mean()
    if tail - head < 0.5 * span:
        other = "close" if operation == "open" else "open"
        raise FitError(f"{src}: the travel moves the wrong way for an {operation_word(operation)} "
                       f"(it looks like a{'n' if other == 'open' else ''} {operation_word(other)})")
    # Motion onset from travel: first sustained rise above the idle level.
    base = np.median(y[: max(int(0.005 * fs), 16)])
    i_move = int(np.argmax(smooth > base + 0.02 * span))
    i_shock, shock_found = _find_shock(capture, i_move, fs, operation)
    tau_range, command_source = None, "latch shock" if shock_found else "first sample"
    if not shock_found and capture.vibration is None and capture.meta.get("command_s") is not None:
        # A coil current's rise (no accelerometer): the command plays the latch shock's role.
        i_cmd = int(round(float(capture.meta["command_s"]) * fs))
        if 0 <= i_cmd < i_move:
            i_shock, shock_found = i_cmd, True
            command_source = str(capture.meta.get("command_source", "coil"))
            depart = (i_move - i_cmd) / fs
            tau_range = (max(0.0, depart - ONSET_BEFORE_DEPARTURE_S), depart + 1e-3)
    if not shock_found and i_move > (ONSET_BEFORE_DEPARTURE_S + 2e-3) * fs:
        # No shock and no command (an accelerometer's shock lost, e.g. filtered out at a low
        # rate): start shortly before the travel departs and search the onset across that span.
        i_shock = i_move - int(ONSET_BEFORE_DEPARTURE_S * fs)
        tau_range, command_source = (0.0, ONSET_BEFORE_DEPARTURE_S + 1e-3), "travel departure"
    lead = int((0.002 if operation == 'open' else 0.012) * fs)
    idle = y[:i_shock] if shock_found and tau_range is None else y[: max(i_move - lead, 0)]
    zero = 0.0
    if take_zero and shock_found and i_shock >= MIN_IDLE:
        # Before the latch shock (or the coil command) the breaker is at rest at the coordinate's
        # zero, so those samples' mean is the transducer's zero in this operation (its keying,
        # its drift since the last one). The model starts from rest at 0: the zero is taken off
        # rather than left for the springs' and the buffer's parameters to absorb (it varies from
        # operation to operation and was the largest part of their spread through a realistic
        # sensor: bench/interval_repeat.py). Without a shock the idle part may hold the first
        # of the motion, so nothing is taken off.
        zero = float(np.mean(y[:i_shock]))
    if idle.size >= MIN_IDLE:
        noise = float(np.std(idle - np.mean(idle), ddof=1))
        noise_source = "pre-trigger"
    else:
        d = np.diff(y[: max(i_move, MIN_IDLE)]) if i_move > 8 else np.diff(y)
        noise = float(mad_sd(d) / np.sqrt(2))
        noise_source = "differences"
    noise = max(noise, 1e-7)
    i_end, t_end = _peak(y, smooth, i_move, fs, operation, noise, stroke, src)
    _check_saturation(capture, i_shock, i_end, src)
    _check_masked(capture, i_shock, i_end, src, operation)
    t_start = i_shock / fs
    sl = slice(i_shock, i_end + 1)
    t = np.arange(i_end + 1 - i_shock) / fs
    if t.size < 0.005 * fs:
        raise FitError(f"{src}: the valid interval is only {t.size / fs * 1e3:.1f} ms long")
    return FitWindow(t, y[sl] - zero, t_start, t_end, noise, noise_source, shock_found, fs,
                     tau_range, command_source, zero)


def _check_masked(capture: Capture, i0: int, i1: int, src: str, operation: str) -> None:
    """Refuse, in words, a window that holds travel samples the recorder marked over-range: they
    are carried filled (a straight line), not measured. Spans outside the window do no harm."""
    channel = capture.meta.get("travel_channel", "travel")
    hit = overlapping(capture.meta.get("masked"), channel, i0, i1)
    if hit:
        fs = capture.sample_rate
        raise FitError(f"{src}: travel {channel} is over-range (marked ∞ or NaN by the recorder) inside the "
                       f"{operation_word(operation)}'s window ({1e3 * i0 / fs:.1f}–{1e3 * i1 / fs:.1f} ms): "
                       + "; ".join(describe(s) for s in hit[:3])
                       + f". The fit cannot use {channel} for this operation: fit another phase "
                         "([channels] travel in the breaker file)")


# 1 / Φ⁻¹(3/4): the MAD of a normal sample times this is its standard deviation.
_MAD_TO_SD = 1.482602218505602


def mad_sd(x: np.ndarray) -> float:
    """Robust standard deviation: the median absolute deviation, scaled to a normal's σ [unit of x].

    scipy.stats.median_abs_deviation(x, scale="normal") gives the same; this is a tenth of its cost
    on a capture's few thousand samples (the warm fit calls it twice)."""
    x = np.asarray(x, dtype=float)
    return _MAD_TO_SD * float(np.median(np.abs(x - np.median(x))))


def operation_word(operation: str) -> str:
    return {"open": "opening", "close": "closing"}.get(operation, operation)


def _moving_average(y, n):
    return y if n <= 1 else uniform_filter1d(np.asarray(y, dtype=float), n, mode="nearest")


def _find_shock(capture: Capture, i_move: int, fs: float, operation: str):
    """Index of the latch-release shock: the first vibration sample above threshold before the
    travel moves. A closing's camshaft runs free for several ms before the output shaft moves,
    so the search reaches further back for closings."""
    vib = capture.vibration
    if vib is None:
        return 0, False
    vib = np.asarray(vib, dtype=float)
    ref = vib[: max(min(i_move, int(0.005 * fs)), 32)]
    centre = float(np.median(ref))
    sd = float(mad_sd(ref))
    threshold = max(float(capture.meta.get("shock_threshold_g", 50.0)), 10.0 * sd)
    lead = 0.005 if operation == "open" else 0.040
    lo = max(i_move - int(lead * fs), 0)
    hit = np.nonzero(np.abs(vib[lo: i_move + 1] - centre) > threshold)[0]
    if hit.size == 0:
        return 0, False
    return lo + int(hit[0]), True


def _peak(y, smooth, i_move, fs, operation, noise, stroke, src):
    """Index and time [s] of the maximum of the operation coordinate.

    A capture may stop exactly at the maximum (the paper's valid interval): that end is complete
    when the speed there is near zero (see :func:`end_speed`); still moving is a truncated capture.
    """
    n_edge = max(int(fs * 0.5e-3), 1)  # the smoothing is padded at the ends: keep out of them
    search = smooth[i_move: max(y.size - n_edge, i_move + 1)]
    i_max = i_move + int(np.argmax(search))
    word = operation_word(operation)
    if operation == "close":
        # The cam dwell holds θ2 at its maximum: the end is where the rise reaches the settled
        # level, taken robustly from the tail after the motion (not from one noisy sample).
        motion = y[i_move:]
        if float(np.median(motion[-max(motion.size // 4, 8):])) < 0.8 * stroke:
            raise FitError(f"{src}: the closing never reaches its end position within the capture "
                           "(truncated capture or the breaker did not close)")
        end = end_speed(y, smooth, i_move, fs)
        if end.moving:
            raise FitError(_truncated_message(src, word, end))
        i_end, t_end = _arrival(y, search, i_move, fs, noise, n_edge)
        if not _settled(y, i_end, fs):
            # No dwell to read the settled level from: the capture stops at the end of the
            # rise, so its last sample is the end.
            return y.size - 1, (y.size - 1) / fs
        return i_end, t_end
    if i_max >= y.size - n_edge - int(END_FIT_S * fs):
        # No peak well inside the capture (a flat top puts the noisy argmax a few ms early):
        # the capture stops at (or just after) the maximum, or an over-damped opening creeps
        # to rest without overtravel. Both are complete if the end speed is near
        # zero; still moving at the end is a truncated capture.
        end = end_speed(y, smooth, i_move, fs)
        if end.moving:
            raise FitError(_truncated_message(src, word, end))
        i_end, t_end = _arrival(y, search, i_move, fs, noise, n_edge)
        if _settled(y, i_end, fs):
            return i_end, t_end  # crept to rest well before the capture ends
        if end.falling:  # the capture runs on past the maximum: end at the fitted top
            t_top = (y.size - 1) / fs + end.t_vertex
            return int(round(t_top * fs)), t_top
        return y.size - 1, (y.size - 1) / fs
    half = int(0.006 * fs)
    lo, hi = max(i_max - half, i_move), min(i_max + half, y.size - 1)
    tt = (np.arange(lo, hi + 1) - i_max) / fs
    coef = np.polyfit(tt, y[lo: hi + 1], 3)
    roots = np.roots(np.polyder(coef))
    roots = roots[np.isreal(roots)].real
    roots = roots[(roots > tt[0]) & (roots < tt[-1]) & (np.polyval(np.polyder(coef, 2), roots) < 0)]
    t_peak = (i_max + (roots[np.argmin(np.abs(roots))] * fs if roots.size else 0.0)) / fs
    return int(round(t_peak * fs)), float(t_peak)


# Span of the end-speed polynomial [s], and the end speed that still counts as zero, as a
# fraction of the stroke's peak speed: a curve cut at its maximum reads within ±2 % at 50 dB,
# one cut 10 ms early 5–30 %.
END_FIT_S = 4e-3
NEAR_ZERO = 0.03


@dataclass(frozen=True)
class EndSpeed:
    """Speed of the operation coordinate at the capture's last sample.

    Attributes
    ----------
    speed : float
        From a quadratic fitted to the last ``END_FIT_S`` [rad/s]; positive = still rising.
    stderr : float
        Its standard error from the fit residuals [rad/s].
    peak_speed : float
        Largest 1 ms average speed of the motion [rad/s].
    t_vertex : float
        Time of the quadratic's maximum relative to the last sample, within ``[-END_FIT_S, 0]`` [s].
    """

    speed: float
    stderr: float
    peak_speed: float
    t_vertex: float

    @property
    def moving(self) -> bool:
        """Still moving: the speed is significantly (2 standard errors) above near-zero."""
        return self.speed - 2.0 * self.stderr > NEAR_ZERO * self.peak_speed

    @property
    def falling(self) -> bool:
        """Significantly (2 standard errors) past the maximum at the last sample."""
        return self.speed + 2.0 * self.stderr < 0.0


def end_speed(y, smooth, i_move: int, fs: float) -> EndSpeed:
    """Judge the end of a capture: speed at the last sample of ``y`` [rad] sampled at ``fs`` [Hz]."""
    n = max(int(END_FIT_S * fs), 8)
    n = min(n, y.size - i_move)
    tt = (np.arange(n) - (n - 1)) / fs
    coef, cov = np.polyfit(tt, y[-n:], 2, cov="unscaled")
    resid = y[-n:] - np.polyval(coef, tt)
    var = float(np.sum(resid**2)) / max(n - 3, 1)
    speed, stderr = float(coef[1]), float(np.sqrt(max(cov[1, 1], 0.0) * var))
    k = max(int(1e-3 * fs), 1)
    motion = smooth[i_move:]
    peak = float(np.max(motion[k:] - motion[:-k])) * fs / k if motion.size > k else 0.0
    t_vertex = -coef[1] / (2.0 * coef[0]) if coef[0] < 0 else 0.0
    return EndSpeed(speed, stderr, max(peak, 0.0), float(np.clip(t_vertex, tt[0], 0.0)))


def _settled(y, i_arrival: int, fs: float) -> bool:
    """Whether the motion rests after ``i_arrival``: at least ``END_FIT_S`` of samples whose
    trend is not significantly (3 standard errors) rising. A slow approach to a maximum the
    capture stops at comes within noise of its tail early but keeps rising."""
    rest = y[i_arrival:]
    if rest.size < END_FIT_S * fs or rest.size < 8:
        return False
    # the least-squares line in closed form: np.polyfit(tt, rest, 1, cov=True)'s slope and its
    # variance (residual variance over n - 2, as polyfit scales it), without the n x 2 lstsq
    n = rest.size
    tt = (np.arange(n) - 0.5 * (n - 1)) / fs
    # (elementwise sums, not BLAS dot products: a threaded BLAS stalls on a busy machine)
    sxx = float(np.sum(tt * tt))
    d = rest - rest.mean()
    slope = float(np.sum(tt * d)) / sxx
    ssr = float(np.sum(d * d)) - slope * slope * sxx
    return bool(slope <= 3.0 * np.sqrt(max(ssr / (n - 2) / sxx, 0.0)))


def _truncated_message(src, word, end: EndSpeed) -> str:
    return (f"{src}: the capture ends before the {word} reaches its maximum travel: it is still "
            f"moving at {end.speed:.2f} rad/s ({100 * end.speed / max(end.peak_speed, 1e-9):.0f} % of its peak "
            "speed) at the last sample (truncated capture)")


def _arrival(y, search, i_move, fs, noise, n_edge):
    """Where a motion that ends at rest reaches its settled level: the first time the smoothed
    curve comes within noise of the plateau, taken robustly from the tail (not one sample)."""
    tol = max(3.0 * noise / np.sqrt(n_edge), 1e-4)
    motion = y[i_move:]
    level = float(np.median(motion[-max(motion.size // 4, 8):]))
    for _ in range(2):  # refine the plateau level on everything after the first arrival
        reached = np.nonzero(search >= level - tol)[0]
        if reached.size == 0:
            raise FitError("cannot find where the motion reaches its end position")
        level = float(np.median(y[i_move + int(reached[0]):]))
    reached = np.nonzero(search >= level - tol)[0]
    if reached.size == 0:
        raise FitError("cannot find where the motion reaches its end position")
    i_end = i_move + int(reached[0])
    return i_end, i_end / fs


def _check_saturation(capture: Capture, i0: int, i1: int, src: str, run: int = 64) -> None:
    """A travel channel pinned at its full-scale code while moving is clipped."""
    lim = capture.travel_limits
    if lim is None:
        return
    seg = np.asarray(capture.travel[i0: i1 + 1], dtype=float)
    span = lim[1] - lim[0]
    for edge in lim:
        at = np.abs(seg - edge) <= 1e-6 * span
        if at.sum() >= run:
            longest = _longest_run(at)
            if longest >= run:
                raise FitError(f"{src}: the travel channel is saturated at {edge:.4f} rad for "
                               f"{longest} consecutive samples during the operation")


def _longest_run(mask):
    if not mask.any():
        return 0
    padded = np.concatenate([[0], mask.astype(int), [0]])
    d = np.diff(padded)
    return int(np.max(np.nonzero(d == -1)[0] - np.nonzero(d == 1)[0]))

