"""The key moments of one operation read from its vibration channel, and the trip latch's time.

Method (the short-time energy key-moment detection of Hsu et al., "Vacuum circuit breaker closing
time key moments detection via vibration monitoring: a run-to-failure study", arXiv 2208.07607,
with the threshold set from the capture's own noise instead of by hand):

1. The short-time energy (STE) ``E_i = sum(x_j^2, j = i-N+1 .. i)`` of the vibration with its rest
   level removed, over ``N`` samples of ``STE_WINDOW_S``.
2. The noise it is judged against comes from the capture's own pre-trigger, before the span in
   which the first shock is searched: its robust standard deviation σ (median absolute deviation)
   and its autocorrelation ρ_j. For Gaussian noise the STE is a scaled chi-square whose effective
   degrees of freedom are ``k = N / (1 + 2 Σ_j (1 - j/N) ρ_j²)`` (exact moments of a sum of squares
   of correlated Gaussians), so white and coloured noise get the same stated false-detection rate.
3. The threshold is the quantile that makes one false first shock in ``1 / FALSE_DETECTION_RATE``
   quiet captures over the whole search span: the union (Bonferroni) bound over the sliding window
   ending at every sample of the span, so the stated rate is an upper bound whatever the windows'
   correlation; the window's mean square over σ̂² is F-distributed (σ̂ from the reference), which
   carries the reference's own length into it. ``bench/vibration_events.py`` measures the rate.
4. Each event's onset is first the STE crossing, then refined to the sample by Maeda's Akaike
   information criterion picker (Maeda 1985, the seismologists' onset picker): the split of the
   samples before the crossing into a noise part and a signal part of different variance.
5. Later events (the latch release, buffer engagement, end stop) are rises of the STE by
   ``JUMP`` over the window before it, above the same threshold: a new shock on a ringing tail.
   Two shocks less than two STE windows (0.5 ms) apart read as one.

Latch time: from the first shock (the trip armature striking the latch) to the start of shaft
motion, which is the travel fit's onset (window start + onset delay), not read from the vibration.
A time is never invented: a weak, clipped, missing, flat or too-short channel gives ``None`` with
the reason in words. Pure: no I/O.
"""

from __future__ import annotations

from functools import lru_cache

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import butter, sosfilt
from scipy import special

STE_WINDOW_S = 0.25e-3
"""Short-time energy window [s]: longer than half a period of the mechanism's ringing (1.5–3 kHz
in the samples and prototypes) so the energy does not flicker within one cycle, short enough to
keep the onset's search to a quarter millisecond before the AIC refinement."""
FALSE_DETECTION_RATE = 1e-4
"""Designed probability that a quiet capture (noise only) shows a first shock [per capture]: a
false first shock is a wrong latch time, so it is made rarer than a missed weak strike (None)."""
HINT_RATE = 0.05
"""When the first clear shock could be the latch release (within ``HINT_NEAR_S`` of the motion),
energy before it above the threshold of this looser false-detection rate is a possible weaker
strike: the latch time is then not read rather than read from the release. The price: about this
fraction of release-only captures give no latch time."""
HINT_NEAR_S = 1.0e-3
"""A first shock this close before the motion may be the release [s] (the samples' 0.4 ms,
prototype B's 0.3–0.5 ms): a strike is further ahead of a healthy latch's motion (1–3 ms)."""
MAX_LATCH_S = 12e-3
"""Longest trip-latch time searched before the motion [s]: a healthy spring mechanism's latch
takes 1–3 ms; a sticking latch several ms more. Shocks earlier than this are not this operation's."""
MIN_NOISE_S = 2e-3
"""Pre-trigger length the noise is taken from [s] (at least MIN_NOISE_SAMPLES): σ of n samples is
then known to ±1/sqrt(2(n-1)), ±4.4 % for 256 samples at 128 kS/s."""
MIN_NOISE_SAMPLES = 64
BAND_HZ = (500.0, 12_000.0)
"""Band the energy is taken in [Hz]: the mechanism's shocks ring at 1.5–5 kHz (the samples and the
prototypes; Hoidalen & Runde 2005 read their patterns below ~20 kHz), while the accelerometer's
white noise fills the whole 0–fs/2: at 128 kS/s the band keeps 18 % of the noise power."""
JUMP = 4.0
"""A later event: the STE rises by this factor (6 dB) over the window just before it."""
OUTLIER_SIGMA = 8.0
"""A pre-trigger sample this many σ from rest (probability ~1e-15 per Gaussian sample) means the
reference is not noise: something already rings there."""
CLIP_FRACTION = 0.10
"""More than this fraction of the search span at a rail: the channel is clipped, not a shock."""
RAIL = 0.999
"""A sample within 0.1 % of the channel's limit is at the rail."""
ONSET_SPREAD_S = 0.3e-3
"""A first shock whose onset's 95 % interval (the AIC weights') is wider than this is not timed [s]:
the issue's tolerance on the latch time."""
END_STOP_TOLERANCE_S = 3e-3
"""An event within this of the travel's end is the end stop [s]."""


class VibrationError(ValueError):
    """The vibration channel cannot be read for this operation: the message says why, in words."""


@dataclass(frozen=True)
class VibrationEvents:
    """What one operation's vibration says.

    Attributes
    ----------
    latch_time_s : float or None
        From the first shock to the start of shaft motion [s]; None when it cannot be read.
    reason : str or None
        Why ``latch_time_s`` is None, in words.
    events : list of dict
        ``{"name", "t_s", "peak_g", "clipped"}``: each event's onset relative to the start of shaft
        motion [s] (negative before it), its peak acceleration [g] and whether the peak is at the
        channel's rail (the peak is then a lower bound).
    noise_g : float or None
        Pre-trigger noise standard deviation [g].
    threshold_g : float or None
        The detection threshold as an rms acceleration over one STE window [g].
    false_detection_rate : float
        Designed false first-shock probability per quiet capture.
    t_motion_s : float
        Start of shaft motion the times are relative to [s from the first sample].
    """

    latch_time_s: float | None
    reason: str | None
    events: list = field(default_factory=list)
    noise_g: float | None = None
    threshold_g: float | None = None
    false_detection_rate: float = FALSE_DETECTION_RATE
    t_motion_s: float = float("nan")
    banded: np.ndarray | None = field(default=None, repr=False, compare=False)
    """The channel band-passed (``band``) from its first sample on, as far as it was read: the
    envelope reuses it rather than filtering again."""

    def event(self, name: str) -> dict | None:
        return next((e for e in self.events if e["name"] == name), None)

    def to_characteristics(self) -> dict:
        """The keys this adds to a fit's ``characteristics`` (JSON-ready)."""
        out = {"latch_time_s": self.latch_time_s,
               "vibration_events": [dict(e) for e in self.events],
               "vibration": {"noise_g": self.noise_g, "threshold_g": self.threshold_g,
                             "false_detection_rate": self.false_detection_rate,
                             "method": "short-time energy, pre-trigger noise threshold, AIC onset"}}
        if self.latch_time_s is None:
            out["latch_time_reason"] = self.reason
        return out


def _null(reason: str, t_motion_s: float, **kw) -> VibrationEvents:
    return VibrationEvents(None, reason, t_motion_s=t_motion_s, **kw)


def short_time_energy(x: np.ndarray, n: int) -> np.ndarray:
    """Trailing short-time energy: ``E[i] = sum(x[i-n+1 .. i]^2)`` [unit^2]; the first n-1 are partial."""
    c = np.concatenate(([0.0], np.cumsum(np.asarray(x, dtype=float) ** 2)))
    i = np.arange(x.size)
    return c[i + 1] - c[np.maximum(i + 1 - n, 0)]


def effective_dof(ref: np.ndarray, n: int) -> float:
    """Effective chi-square degrees of freedom of an n-sample energy of noise like ``ref``."""
    return effective_dofs(ref, (n,))[0]


def effective_dofs(ref: np.ndarray, ns) -> list[float]:
    """``effective_dof(ref, n)`` for each n of ``ns``, from one autocorrelation of ``ref``."""
    r = ref - ref.mean()
    var = float(np.sum(r * r)) / r.size
    if var <= 0:
        return [float(n) for n in ns]
    top = min(max(ns), r.size // 4)
    if top > 1:  # the autocorrelation at every lag at once (Wiener–Khinchin, zero-padded: not circular)
        spec = np.fft.rfft(r, 2 * r.size)
        rho_all = np.fft.irfft(spec * np.conj(spec), 2 * r.size)[1:top] / (r.size * var)
    else:
        rho_all = np.zeros(0)
    out = []
    for n in ns:
        lags = np.arange(1, min(n, r.size // 4))
        rho = rho_all[:lags.size]
        out.append(float(n / (1.0 + 2.0 * np.sum((1.0 - lags / n) * rho**2))))
    return out


def energy_threshold(sigma: float, k: float, n: int, windows: float,
                     rate: float = FALSE_DETECTION_RATE, ref_dof: float = np.inf) -> float:
    """STE threshold [unit^2] for noise of σ with k effective dof in an n-sample window, so that
    ``windows`` windows exceed it with probability ``rate`` altogether (Bonferroni). σ estimated
    from a reference of ``ref_dof`` effective dof: the window's mean square over σ² is then
    F(k, ref_dof)-distributed, which carries σ's own uncertainty into the threshold."""
    p = rate / max(windows, 1.0)
    # scipy.stats' chi2.isf and f.isf, called through the special functions they wrap (50x less overhead)
    ratio = special.chdtri(k, p) / k if not np.isfinite(ref_dof) else special.fdtri(k, ref_dof, 1.0 - p)
    return float(sigma**2 * n * ratio)


def band(x: np.ndarray, fs: float) -> np.ndarray:
    """The mechanism's band of ``x``: a causal band-pass BAND_HZ (the upper edge below 0.45 fs).

    Causal, not zero-phase: a zero-phase filter runs backwards too, and would spread a 400 g
    release shock's ringing milliseconds before it, above a weak strike's threshold. A causal
    filter's response cannot start before the shock; its delay (~30 µs) is left in the onset."""
    sos = _band_sos(float(fs))
    if sos is None:
        return x - np.median(x)
    return sosfilt(sos.copy(), x - x[0])  # sosfilt may write its sections: never the cached ones


@lru_cache(maxsize=8)
def _band_sos(fs: float):
    """The band-pass's second-order sections at ``fs`` [Hz], designed once per sample rate."""
    lo, hi = BAND_HZ[0], min(BAND_HZ[1], 0.45 * fs)
    if hi <= 2 * lo:
        return None
    sos = butter(4, [lo, hi], btype="bandpass", fs=fs, output="sos")
    return sos


def aic_onset(x: np.ndarray) -> int:
    """Maeda's AIC picker: the split index of ``x`` into a low- and a high-variance part."""
    return aic_pick(x)[0]


def aic_pick(x: np.ndarray) -> tuple[int, int]:
    """Maeda's AIC split of ``x`` and the width [samples] of its 95 % interval: the splits whose
    Akaike weights ``exp(-(AIC_k - AIC_min) / 2)`` hold the central 95 % (Burnham & Anderson's
    model weights, here over the candidate onsets)."""
    m = x.size
    if m < 8:
        return m // 2, m
    c1, c2 = np.cumsum(x), np.cumsum(x**2)
    k = np.arange(2, m - 2)
    v1 = c2[k - 1] / k - (c1[k - 1] / k) ** 2
    n2 = m - k
    s1, s2 = c1[-1] - c1[k - 1], c2[-1] - c2[k - 1]
    v2 = s2 / n2 - (s1 / n2) ** 2
    tiny = 1e-30
    aic = k * np.log(np.maximum(v1, tiny)) + (n2 - 1) * np.log(np.maximum(v2, tiny))
    j = int(np.argmin(aic))
    w = np.exp(-0.5 * (aic - aic[j]))
    c = np.cumsum(w) / np.sum(w)
    lo, hi = int(np.searchsorted(c, 0.025)), int(np.searchsorted(c, 0.975))
    return int(k[j]), int(hi - lo + 1)


def detect_events(vibration, sample_rate: float, t_motion_s: float, operation: str = "open", *,
                  t_end_s: float | None = None, limits: tuple | None = None,
                  source: str = "capture", rate: float = FALSE_DETECTION_RATE,
                  read_span_s: float = 0.0) -> VibrationEvents:
    """Events and latch time of one operation.

    Parameters
    ----------
    vibration : array_like or None
        Mechanism acceleration [g], sample-aligned with the travel.
    sample_rate : float
        [Hz]
    t_motion_s : float
        Start of shaft motion (the travel fit's onset) [s from the first sample].
    operation : {"open", "close"}
    t_end_s : float, optional
        End of the travel (the valid interval's end) [s], to name the end stop.
    limits : tuple, optional
        The channel's representable range [g], for clipping.
    rate : float
        Designed false-detection probability per quiet capture.
    read_span_s : float
        Band-pass at least this long after the start of motion [s] (the envelope's span), so the
        result's ``banded`` serves it.

    Returns
    -------
    VibrationEvents
        Never raises for a bad channel: the latch time is then None with the reason.
    """
    t_motion = float(t_motion_s)
    fs = float(sample_rate)
    if vibration is None:
        return _null("no vibration channel in the capture: the latch time needs the accelerometer", t_motion)
    raw = np.asarray(vibration, dtype=float)
    if not np.isfinite(fs) or fs <= 0:
        return _null(f"{source}: invalid sample rate {fs}", t_motion)
    if not np.isfinite(t_motion):
        return _null("the start of motion is unknown, so the latch time cannot be counted", t_motion)
    n = max(8, int(round(STE_WINDOW_S * fs)))
    i_motion = int(round(t_motion * fs))
    if i_motion <= 0 or i_motion >= raw.size:
        return _null(f"the vibration channel ({raw.size} samples) does not cover the start of motion "
                     f"at {t_motion * 1e3:.1f} ms", t_motion)
    i_stop = raw.size if t_end_s is None else min(raw.size, int(round((t_end_s + 5e-3) * fs)))
    if not np.all(np.isfinite(raw[:i_stop])):
        bad = int(np.argmax(~np.isfinite(raw[:i_stop])))
        return _null(f"the vibration channel holds NaN or infinite samples (from {bad / fs * 1e3:.1f} ms): "
                     "a broken sensor or cable", t_motion)
    min_noise = max(MIN_NOISE_SAMPLES, int(round(MIN_NOISE_S * fs)))
    search0 = i_motion - int(round(MAX_LATCH_S * fs))
    if i_motion < min_noise + 4 * n:
        return _null(f"the pre-trigger holds only {i_motion / fs * 1e3:.1f} ms before the motion: too short "
                     f"to hold the first shock and the {MIN_NOISE_S * 1e3:.0f} ms of noise it is judged against",
                     t_motion)
    short_pre = search0 < min_noise
    search0 = max(search0, min_noise)
    ref_raw = raw[:search0]
    rest = float(np.median(ref_raw))
    x = raw - rest
    ref = x[:search0]
    head = ref_raw[: min(ref_raw.size, 4096)]
    lo_v, hi_v = head.min(), head.max()
    if lo_v == hi_v or np.all((head == lo_v) | (head == hi_v)):  # at most two values
        return _null("the vibration channel is flat before the operation (constant or two-level): "
                     "a disconnected or dead accelerometer", t_motion)
    # causal: the band-passed prefix is the whole channel's, so only what is read is looked at
    # (to the travel's end, the envelope's span, and the 3 ms an event's peak is read over)
    upto = min(raw.size, max(i_stop, i_motion + int(round(read_span_s * fs))) + int(round(3e-3 * fs)))
    lo_rail, hi_rail = _rails(raw, limits)
    prefix = raw[:upto]
    at_rail = (prefix <= lo_rail) | (prefix >= hi_rail)
    if np.any(at_rail[:search0]):
        return _null("the vibration channel is clipped at rest (at its rail before the operation): "
                     "check the accelerometer's range and offset", t_motion)
    span_rail = float(np.mean(at_rail[search0:i_motion])) if i_motion > search0 else 0.0
    if span_rail > CLIP_FRACTION:
        return _null(f"the vibration channel is clipped: {span_rail:.0%} of the {((i_motion - search0) / fs) * 1e3:.1f} ms "
                     "before the motion sit at the channel's rail, so the shocks' onsets are lost", t_motion)
    sigma = float(np.median(np.abs(ref))) * 1.4826  # ref's median is 0: rest was taken off
    if sigma > 0 and np.max(np.abs(ref)) > OUTLIER_SIGMA * sigma:
        where = int(np.argmax(np.abs(ref) > OUTLIER_SIGMA * sigma))
        return _null(f"the vibration already rings {(i_motion - where) / fs * 1e3:.1f} ms before the motion, "
                     f"earlier than the {MAX_LATCH_S * 1e3:.0f} ms a latch can take: the pre-trigger holds no quiet "
                     "noise to judge the first shock against", t_motion, noise_g=sigma)
    noise_g = float(np.std(ref))
    x = band(x[:upto], fs)
    ref = x[n:search0]  # the filter's start-up left out
    sigma = float(np.std(ref))
    if sigma <= 0:
        return _null("the vibration channel is flat before the operation: a dead accelerometer", t_motion)
    noise_kw = {"noise_g": noise_g, "banded": x}
    k, quarter = effective_dofs(ref, (n, ref.size // 4))
    span = i_motion - search0
    ref_dof = quarter * 4
    threshold = energy_threshold(sigma, k, n, span, rate, ref_dof=ref_dof)
    thr_g = float(np.sqrt(threshold / n))
    noise_kw["threshold_g"] = thr_g
    E = short_time_energy(x, n)
    hits = np.nonzero(E[search0 + n: i_stop] > threshold)[0]
    if hits.size == 0:
        return _null(f"no shock above the detection threshold ({thr_g:.2f} g rms over "
                     f"{STE_WINDOW_S * 1e3:.2f} ms, from {sigma:.2f} g of noise) in the "
                     f"{(i_motion - search0) / fs * 1e3:.0f} ms before the motion: the trip strike is too weak "
                     "to time", t_motion, **noise_kw)
    i_first = search0 + n + int(hits[0])
    if short_pre and i_first < search0 + 2 * n:
        return _null(f"the pre-trigger is too short to hold the first shock: the vibration is already above "
                     f"the noise {(i_motion - i_first) / fs * 1e3:.1f} ms before the motion, at the "
                     "capture's start", t_motion, **noise_kw)
    spread: list = []
    onsets = _onsets(x, E, threshold, n, i_first, i_stop, spread)
    hint = energy_threshold(sigma, k, n, span, HINT_RATE, ref_dof=ref_dof)
    before = E[search0 + n: max(onsets[0] - n, search0 + n)]
    near = i_motion - HINT_NEAR_S * fs <= onsets[0] < i_motion
    if near and before.size and np.max(before) > hint:
        i_hint = search0 + n + int(np.argmax(before > hint))
        return VibrationEvents(None, f"a possible trip strike {(i_motion - i_hint) / fs * 1e3:.2f} ms before the motion, "
                               f"too weak to time (below the {thr_g:.2f} g threshold), before the first clear shock "
                               f"at {(i_motion - onsets[0]) / fs * 1e3:.2f} ms: the latch time is not read",
                               _name(onsets, x, at_rail, fs, i_motion, operation, n, t_end_s),
                               t_motion_s=t_motion, **noise_kw)
    events = _name(onsets, x, at_rail, fs, i_motion, operation, n, t_end_s)
    first = next(e for e in events if e["name"] == "first_shock")
    if spread and spread[0] / fs > ONSET_SPREAD_S and first["t_s"] < 0:
        return VibrationEvents(None, f"the first shock ({-first['t_s'] * 1e3:.2f} ms before the motion, "
                               f"{first['peak_g']:.1f} g) is too weak to time: its onset lies anywhere in "
                               f"{spread[0] / fs * 1e3:.2f} ms", events, t_motion_s=t_motion, **noise_kw)
    if first["t_s"] >= 0:
        return VibrationEvents(None, f"no shock before the motion: the first one comes "
                               f"{first['t_s'] * 1e3:.2f} ms after the shaft starts to move (a trip strike "
                               "the accelerometer does not see)", events, t_motion_s=t_motion, **noise_kw)
    return VibrationEvents(float(-first["t_s"]), None, events, t_motion_s=t_motion, **noise_kw)


def _rails(raw, limits):
    if limits is not None and all(np.isfinite(v) for v in limits):
        lo, hi = float(limits[0]), float(limits[1])
        return lo + (1.0 - RAIL) * abs(lo) if lo < 0 else lo, hi * RAIL if hi > 0 else hi
    lo, hi = float(np.min(raw)), float(np.max(raw))
    # no stated range: a value repeated at the extreme (3+ samples) is a rail
    lo_rail = lo if np.count_nonzero(raw == lo) >= 3 else -np.inf
    hi_rail = hi if np.count_nonzero(raw == hi) >= 3 else np.inf
    return lo_rail, hi_rail


def _refine(x, i_cross, n, floor, spread=None):
    """AIC-refined onset of the burst whose STE crosses at ``i_cross`` (not before ``floor``);
    ``spread`` (a list) receives the width of the onset's 95 % interval [samples]."""
    a = max(floor, i_cross - 3 * n)
    b = min(x.size, i_cross + n // 4 + 1)
    if b - a < 8:
        return i_cross
    i, width = aic_pick(x[a:b])
    if spread is not None:
        spread.append(width)
    return a + i


def _onsets(x, E, threshold, n, i_first, i_stop, spread=None):
    """Onset indices of the first shock and of each later rise of the STE."""
    out = [_refine(x, i_first, n, max(0, i_first - 3 * n), spread)]
    i = out[0] + 2 * n  # the STE before a burst's second window is still the noise's
    # the rises from there to the stop only (E[j - n] is the energy one window earlier)
    lo = max(i, n)
    seg = E[lo:i_stop]
    rise = np.zeros(i_stop, dtype=bool)
    rise[lo:i_stop] = (seg > threshold) & (seg > JUMP * E[lo - n:i_stop - n])
    while i < i_stop:
        nxt = np.nonzero(rise[i:i_stop])[0]
        if nxt.size == 0:
            break
        j = i + int(nxt[0])
        onset = _refine(x, j, n, out[-1] + n)
        if onset > out[-1] + n:
            out.append(onset)
        i = max(j, onset) + 2 * n
    return out


def _name(onsets, x, at_rail, fs, i_motion, operation, n, t_end_s):
    """Name the onsets: first shock, latch release (the last before the motion), buffer engagement
    (openings: the strongest in the motion), end stop (the one nearest the travel's end)."""
    events = []
    for k, i in enumerate(onsets):
        j = onsets[k + 1] if k + 1 < len(onsets) else min(x.size, i + int(3e-3 * fs))
        seg = slice(i, max(j, i + 1))
        events.append({"name": "impact", "t_s": (i - i_motion) / fs,
                       "peak_g": float(np.max(np.abs(x[seg]))), "clipped": bool(np.any(at_rail[seg]))})
    events[0]["name"] = "first_shock"
    before = [e for e in events if e["t_s"] < 1e-4]
    if len(before) >= 2:
        before[-1]["name"] = "latch_release"
    if t_end_s is not None:
        t_end_rel = t_end_s - i_motion / fs
        after = [e for e in events if e["t_s"] > 1e-3 and e["name"] == "impact"]
        near = [e for e in after if abs(e["t_s"] - t_end_rel) <= END_STOP_TOLERANCE_S]
        if near:
            min(near, key=lambda e: abs(e["t_s"] - t_end_rel))["name"] = "end_stop"
        if operation == "open":
            mid = [e for e in after if e["name"] == "impact" and e["t_s"] < t_end_rel - 0.5e-3]
            if mid:
                max(mid, key=lambda e: e["peak_g"])["name"] = "buffer_engagement"
    for e in events:
        e["t_s"] = float(e["t_s"])
    return events
