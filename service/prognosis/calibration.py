"""Online calibration of the prognosis's interval on the breaker's own forecast errors (issue 55).

Pure: no I/O, no clock; the state is plain JSON (``to_dict``/``from_dict``) stored with the
prognosis. Method (docs/prognosis.md, "Calibration on the breaker's own errors"):

- **Forecasts.** Each prognosis leaves its level's 5/50/95 % quantiles at a grid of openings
  ahead (``FORECAST_AHEAD``) and its crossing interval. The last ``PENDING`` forecasts stay
  pending until the next restart.
- **Scores.** Each good fit that arrives is scored against every pending forecast, at the
  horizon h = fits since that forecast: the probability integral transform (PIT, Dawid 1984)
  u = F(y) of the fit's predictive, the level's split normal through its 5/50/95 % quantiles
  with the run-to-run noise sigma^2 / w added to each half. Scores fall in horizon bands from
  ``HORIZONS`` (1-4, 5-19, >= 20 openings: the k = 1, 5, 20 step forecasts).
- **Correction.** Each band and tail runs adaptive conformal inference (Gibbs & Candes 2021,
  NeurIPS 34, eq. 2) with a decaying step (Angelopoulos, Barber & Bates 2024): the tail's level
  a moves by eta_t (alpha - err) with err = 1{u < a} (lower) or 1{u > 1 - a} (upper): a breaker
  that surprises widens its tail, one that does not narrows it.
- **Into the crossing.** The corrected tail levels are the probabilities at which the crossing's
  quantiles are read (the level lower than forecast is the earlier crossing for a falling
  limit). The longest band with ``MIN_SCORES`` scores decides: the crossing is tens to hundreds
  of openings ahead. (Rescaling the level's spread by the tail's z-ratio with the noise's share
  taken out was tried first: ill-conditioned where the noise dominates, it narrowed the own
  bench 0.90 -> 0.86 at 140 histories.)
- **Crossings.** When the trend passes its limit, each pending crossing interval is judged
  (early, inside, late) and the same update moves an offset of the crossing's tail levels.
- **Restart.** A baseline reset or a logged repair restarts the calibration with the history
  (``key`` differs): the old forecasts were of another mechanism.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from scipy import special

ALPHA = 0.05  # each tail of the 90 % interval [-]
Z_ALPHA = 1.6448536269514722  # Phi^-1(1 - ALPHA)
# ACI's step decays as eta_t = ETA_1 t^-(1/2 + EPSILON) (Angelopoulos, Barber & Bates 2024,
# "Online conformal prediction with decaying step sizes", ICML): the long-run miss rate is still
# alpha for any sequence, and where the breaker's errors are stable the level settles on the one
# that misses alpha of them. A fixed step (Gibbs & Candes's gamma) makes the level a random walk
# when the scores come in runs, as the scores of one forecast do (they share its trend's error):
# 200 hits in a row move it by 200 gamma alpha. EPSILON = 0.1 is theirs; ETA_1 = ALPHA: the
# first miss can move a tail from alpha to zero, no further.
ETA_1 = 0.05
EPSILON = 0.1
# The crossing's offsets move by GAMMA per crossing judged (few per repair: a fixed step).
GAMMA = 0.02
# Horizon bands' lower edges [openings]: the k = 1, 5, 20 step forecasts of issue 55.
HORIZONS = (1, 5, 20)
# Scores a band needs before it moves the crossing: with fewer, one surprise is a tail's whole
# evidence (20 scores hold one expected miss per tail).
MIN_SCORES = 20
# The tail level stays inside [A_MIN, A_MAX]: a 0 would be an infinite interval (ACI's own
# fallback), 0.5 a one-sided interval that holds nothing on that side.
A_MIN, A_MAX = 1e-3, 0.5
# Openings ahead at which a forecast keeps its level quantiles (log-spaced; interpolated between).
FORECAST_AHEAD = (1, 2, 3, 5, 8, 13, 20, 30, 50, 80, 130, 200, 300, 500, 800, 1300, 2000)
PENDING = 4  # forecasts scored at once: the latest prognoses' (older ones are superseded)
CROSSING_PENDING = 20
# A fit further than this many predictive sds from the forecast's median is a gross fit error
# (the trend drops it too: forecast.REJECT_Z) and is not scored.
REJECT_Z = 4.0


@dataclass
class Tails:
    """One horizon band's ACI state: tail levels a_lo, a_hi [-], scores n, and the mean share of
    the level in the predictive variance v_lo, v_hi [-]."""

    a_lo: float = ALPHA
    a_hi: float = ALPHA
    n: int = 0
    v_lo: float = 0.0
    v_hi: float = 0.0
    miss_lo: int = 0
    miss_hi: int = 0


@dataclass
class Calibration:
    """The calibration of one breaker's parameter since ``key`` (its history's start).

    forecasts : pending forecasts, each {"seen": fits since it was made, "ahead": [openings],
        "median", "lo", "hi": the level's quantiles [unit], compensated}; bands : horizon band's
        lower edge -> Tails; crossing : {"lo", "hi": offsets of the crossing's tail levels [-],
        "n": crossings judged, "pending": [[fits scored when made, p05, p95 or None]]};
    fits : fits scored since the restart; last_id, last_time : the last operation scored or
        forecast from (its id and ISO time: a retried fit is not scored twice, and the worker reads
        only the fits after it)
    """

    key: str | None = None
    forecasts: list = field(default_factory=list)
    bands: dict = field(default_factory=lambda: {k: Tails() for k in HORIZONS})
    crossing: dict = field(default_factory=lambda: {"lo": 0.0, "hi": 0.0, "n": 0, "pending": []})
    fits: int = 0
    last_id: int | None = None
    last_time: str | None = None

    def to_dict(self) -> dict:
        return {"version": 1, "key": self.key, "forecasts": self.forecasts,
                "bands": {str(k): vars(t).copy() for k, t in self.bands.items()},
                "crossing": {**self.crossing, "pending": [list(p) for p in self.crossing["pending"]]},
                "fits": self.fits, "last_id": self.last_id, "last_time": self.last_time}

    @classmethod
    def from_dict(cls, d: dict | None, key: str | None = None) -> Calibration:
        """The stored state, or a fresh one when there is none or it belongs to another history
        (``key`` given and different: a reset or a logged repair since)."""
        if not d or d.get("version") != 1 or (key is not None and d.get("key") != key):
            return cls(key=key)
        bands = {k: Tails() for k in HORIZONS}
        for k, t in (d.get("bands") or {}).items():
            if int(k) in bands:
                bands[int(k)] = Tails(**t)
        cr = d.get("crossing") or {}
        return cls(key=d.get("key"), forecasts=[dict(f) for f in d.get("forecasts") or []], bands=bands,
                   crossing={"lo": float(cr.get("lo", 0.0)), "hi": float(cr.get("hi", 0.0)), "n": int(cr.get("n", 0)),
                             "pending": [list(p) for p in cr.get("pending") or []]},
                   fits=int(d.get("fits", 0)), last_id=d.get("last_id"), last_time=d.get("last_time"))


def band_of(h: int) -> int:
    """The horizon band (its lower edge) of a score h openings ahead."""
    return max(k for k in HORIZONS if h >= k)


def _interp(x: float, xs, ys) -> float:
    """Linear interpolation in ``xs`` (increasing), held flat beyond its ends."""
    if x <= xs[0]:
        return float(ys[0])
    for i in range(1, len(xs)):
        if x <= xs[i]:
            t = (x - xs[i - 1]) / (xs[i] - xs[i - 1])
            return float(ys[i - 1] + t * (ys[i] - ys[i - 1]))
    return float(ys[-1])


def pit(value: float, median: float, lo: float, hi: float, noise_sd: float) -> tuple[float, float, float]:
    """(u = F(value), level's variance share below and above the median [-]) of the split normal
    through the level's 5/50/95 % quantiles (lo, median, hi) [unit] plus N(0, noise_sd^2) [unit]
    on each half, its halves' sds sqrt(s^2 + noise_sd^2)."""
    s_lo, s_hi = max(median - lo, 0.0) / Z_ALPHA, max(hi - median, 0.0) / Z_ALPHA
    n2 = noise_sd * noise_sd
    sd_lo, sd_hi = math.sqrt(s_lo * s_lo + n2), math.sqrt(s_hi * s_hi + n2)
    v_lo = s_lo * s_lo / (sd_lo * sd_lo) if sd_lo > 0 else 0.0
    v_hi = s_hi * s_hi / (sd_hi * sd_hi) if sd_hi > 0 else 0.0
    if sd_lo <= 0 or sd_hi <= 0:
        return (0.5 if value == median else (0.0 if value < median else 1.0)), v_lo, v_hi
    # Each half keeps probability 1/2 so that the median stays the median.
    z = (value - median) / (sd_lo if value < median else sd_hi)
    return float(special.ndtr(z)), v_lo, v_hi


def step(t: int) -> float:
    """The step of the t-th score (1-based) [-]: ETA_1 t^-(1/2 + EPSILON) (Angelopoulos, Barber &
    Bates 2024)."""
    return ETA_1 * t ** -(0.5 + EPSILON)


def _aci(a: float, err: bool, t: int) -> float:
    """Gibbs & Candes (2021), eq. 2, with the decaying step: a_{t+1} = a_t + eta_t (alpha - err_t),
    kept in [A_MIN, A_MAX]."""
    return min(max(a + step(t) * (ALPHA - float(err)), A_MIN), A_MAX)


def score(cal: Calibration, value: float, noise_sd: float, operation_id: int | None = None,
          time: str | None = None) -> Calibration:
    """The state after one good fit: ``value`` compensated as the forecasts are [unit],
    ``noise_sd`` its run-to-run sd sigma / sqrt(w) [unit], its operation's id and ISO time.
    O(PENDING): a few microseconds."""
    if operation_id is not None and cal.last_id is not None and operation_id <= cal.last_id:
        return cal
    bands = {k: replace(t) for k, t in cal.bands.items()}
    forecasts = []
    for f in cal.forecasts:
        h = int(f["seen"]) + 1
        med = _interp(h, f["ahead"], f["median"])
        lo, hi = _interp(h, f["ahead"], f["lo"]), _interp(h, f["ahead"], f["hi"])
        sd = math.hypot((hi - lo) / (2 * Z_ALPHA), noise_sd)
        if h <= f["ahead"][-1] and (sd <= 0 or abs(value - med) <= REJECT_Z * sd):
            u, v_lo, v_hi = pit(value, med, lo, hi, noise_sd)
            t = bands[band_of(h)]
            miss_lo, miss_hi = u < t.a_lo, u > 1.0 - t.a_hi
            t.n += 1
            t.a_lo, t.a_hi = _aci(t.a_lo, miss_lo, t.n), _aci(t.a_hi, miss_hi, t.n)
            t.miss_lo += int(miss_lo)
            t.miss_hi += int(miss_hi)
            t.v_lo += (v_lo - t.v_lo) / t.n
            t.v_hi += (v_hi - t.v_hi) / t.n
        forecasts.append({**f, "seen": h})
    return replace(cal, forecasts=forecasts, bands=bands, fits=cal.fits + 1,
                   last_id=operation_id if operation_id is not None else cal.last_id,
                   last_time=time if time is not None else cal.last_time)


def issue(cal: Calibration, ahead, median, lo, hi, crossing: tuple | None = None, *,
          operation_id: int | None = None, time: str | None = None) -> Calibration:
    """The state after a prognosis: its level's quantiles [unit] at ``ahead`` openings [openings]
    become a pending forecast, and its crossing interval (p05, p95 or None) [openings] a pending
    crossing (None: no crossing forecast). ``operation_id``, ``time``: the prognosis's last fit
    (the fits after it are the ones its forecast is scored on)."""
    f = {"seen": 0, "ahead": [float(a) for a in ahead], "median": [float(x) for x in median],
         "lo": [float(x) for x in lo], "hi": [float(x) for x in hi]}
    pending = list(cal.crossing["pending"])
    if crossing is not None and crossing[0] is not None:
        pending = (pending + [[cal.fits, float(crossing[0]), None if crossing[1] is None else float(crossing[1])]])
        pending = pending[-CROSSING_PENDING:]
    out = replace(cal, forecasts=(cal.forecasts + [f])[-PENDING:], crossing={**cal.crossing, "pending": pending})
    if operation_id is not None and (cal.last_id is None or operation_id > cal.last_id):
        out = replace(out, last_id=operation_id, last_time=time)
    return out


def crossed(cal: Calibration) -> Calibration:
    """The state when the trend has passed its limit: every pending crossing interval is judged
    against the openings it actually took (fits scored since it was made), then cleared."""
    lo, hi, n = cal.crossing["lo"], cal.crossing["hi"], cal.crossing["n"]
    for made, p05, p95 in cal.crossing["pending"]:
        took = cal.fits - made
        # The offsets move the tail levels themselves, in the same [A_MIN - ALPHA, A_MAX - ALPHA] range.
        lo = min(max(lo + GAMMA * (ALPHA - float(took < p05)), A_MIN - ALPHA), A_MAX - ALPHA)
        hi = min(max(hi + GAMMA * (ALPHA - float(p95 is not None and took > p95)), A_MIN - ALPHA), A_MAX - ALPHA)
        n += 1
    return replace(cal, crossing={"lo": lo, "hi": hi, "n": n, "pending": []})


def deciding_band(cal: Calibration) -> int | None:
    """The longest horizon band with ``MIN_SCORES`` scores, or None."""
    ready = [k for k, t in cal.bands.items() if t.n >= MIN_SCORES]
    return max(ready) if ready else None


def levels(cal: Calibration | None, direction: str) -> tuple[float, float]:
    """(early, late) probabilities [-] at which the crossing's 5 % and 95 % quantiles are read:
    (ALPHA, 1 - ALPHA) uncorrected. For a falling limit the early crossing is the level's lower
    tail, for a rising one its upper tail."""
    if cal is None:
        return ALPHA, 1.0 - ALPHA
    k = deciding_band(cal)
    early = late = ALPHA
    if k is not None:
        t = cal.bands[k]
        early, late = (t.a_lo, t.a_hi) if direction == "falling" else (t.a_hi, t.a_lo)
    early = min(max(early + cal.crossing["lo"], A_MIN), A_MAX)
    late = min(max(late + cal.crossing["hi"], A_MIN), A_MAX)
    return early, 1.0 - late


def summary(cal: Calibration, direction: str | None) -> dict:
    """What the answer shows of the calibration: the levels used and each band's scores."""
    early, late = levels(cal, direction or "falling")
    return {"levels": [round(early, 4), round(late, 4)], "band": deciding_band(cal),
            "scores": {str(k): {"n": t.n, "a_lo": round(t.a_lo, 4), "a_hi": round(t.a_hi, 4),
                                "miss_lo": t.miss_lo, "miss_hi": t.miss_hi}
                       for k, t in cal.bands.items()},
            "crossings_judged": cal.crossing["n"]}
