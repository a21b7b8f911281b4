"""The multi-condition dataset (paper Section 4.5): captures of one breaker at several spring
settings, with run-to-run spread, fitted once and cached.

One seam makes every capture: :func:`make_capture` ``(spec, condition, index)``. It builds the
breaker of that condition and run (spring pre-compression step, friction and buffer-damping
spread), simulates it on the virtual prototype (issue 6) with the chosen physical effects — or on
the reduced model when ``spec.source == "reduced"`` — and records it like the DAQ would (noise,
16-bit quantisation, latch shock). :func:`build_dataset` fits every capture in a process pool and
keeps the estimates and the baselines' raw-travel features in an ``.npz`` so the classification
and robustness studies do not refit.

The Table 9 set (issue 22) adds field nuisance on the same seam: trigger jitter, sensor offset
and gain, per-capture SNR (:func:`draw_recording`, a stream of its own so the clean sets stay
bit-identical), and a second unit of the design drawn within manufacturing tolerance
(:func:`unit_breaker`); the fit of every unit gets the design breaker, never the drawn one.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..acquisition.synthetic import synthesize_capture
from ..estimation import FitError, fit_capture
from ..mechanics.breaker import CLOSING_PARAMETERS, OPENING_PARAMETERS, Breaker
from .common import DEFAULT_WORKERS, load_reference, pool_map

STEP_M = 3.5e-3            # pre-compression added per condition: two turns of the plate nut [m]
FEATURE_WINDOW_S = 0.085   # raw-travel window the baselines see, from the first sample [s]
FEATURE_POINTS = 256       # resampled length of that window [-]
SETTLED_S = 0.005          # a closing's last 5 ms: on its stop (the record runs 15 ms past the motion)
NOISE_RAD = 0.0015         # DAQ travel noise of the paper's sensor [rad]
# A pair's closing fit searches CC up to this multiple of the top setting's design CC: friction
# +10 % of TCf (+6 % of CC), the closing fit's bias on the prototype (+10 %, conditions.json) and
# a unit's ±3 % J2 compound to +20 %; the breaker file's 12000 s^-2 would clip them.
PAIR_CC_HEADROOM = 1.25


@dataclass(frozen=True)
class DatasetSpec:
    """Everything that decides the captures of one dataset (hashed into the cache name).

    Attributes
    ----------
    operation : {"open", "close"}
    conditions : int
        Number of spring settings; condition k (0-based) adds ``k·STEP_M`` of pre-compression
        (xO1 for openings, xC0 for closings).
    per_condition : int
        Captures per condition.
    seed : int
    source : {"prototype", "reduced"}
        Simulator: the virtual prototype with effects, or the reduced model the fitter assumes.
    effects_scale : float
        Multiplier on the prototype's ``REALISTIC`` strengths [-] (each capped at ``UPPER``).
    noise_rad : float
        Travel noise standard deviation [rad].
    friction_spread : float
        Half-width of the uniform run-to-run spread of the resistance torque (TOf or TCf) [-].
    damping_spread : float
        Half-width of the uniform spread of the buffer damping cb (oil temperature) [-].
    onset_jitter_s : float
        Half-width of the uniform spread of the latch-shock-to-motion delay [s] (0: fixed).
    trigger_delay_s : (float, float) or None
        Range of the uniform delay from the record start to the onset of motion [s] (trigger
        jitter); None: the fixed 20 ms idle lead of ``synthesize_capture``.
    offset_rad : float
        Half-width of the uniform sensor zero offset [rad].
    gain_spread : float
        Half-width of the uniform sensor gain error [-].
    snr_db_range : (float, float) or None
        Range of the uniform per-capture SNR [dB]; overrides ``noise_rad`` when set.
    unit : int
        Which breaker of the design: 1 is the reference itself; any other number is a unit
        drawn within the manufacturing tolerances below (seeded by ``seed`` and ``unit``).
    tolerance : float
        Half-width of the uniform manufacturing spread of kO, J2 and cb for units other than 1 [-].
    alpha0_tolerance_rad : float
        Half-width of the uniform spread of the buffer engagement angle α0 for those units [rad].
    pair : bool
        Close–open pairs (issue 32): the setting is the opening spring's nut, which raises both
        xO0 and xO1 by ``k·STEP_M``; the run state (one friction factor on TOf and TCf, one
        buffer-damping factor) is drawn from a stream shared by the closing and the opening of
        run ``index``, so the two specs that differ only in ``operation`` make the two halves
        of one pair. The fit gets the design breaker (the setting is what is inferred) and,
        for closings, the design DC.
    """

    operation: str = "open"
    conditions: int = 6
    per_condition: int = 40
    seed: int = 2026
    source: str = "prototype"
    effects_scale: float = 0.5
    noise_rad: float = NOISE_RAD
    friction_spread: float = 0.02
    damping_spread: float = 0.03
    onset_jitter_s: float = 0.0
    trigger_delay_s: tuple | None = None
    offset_rad: float = 0.0
    gain_spread: float = 0.0
    snr_db_range: tuple | None = None
    unit: int = 1
    tolerance: float = 0.0
    alpha0_tolerance_rad: float = 0.0
    pair: bool = False

    @property
    def field_nuisance(self) -> bool:
        """Whether the recording carries trigger, sensor or SNR nuisance (the field dataset)."""
        return bool(self.trigger_delay_s or self.offset_rad or self.gain_spread or self.snr_db_range)

    @property
    def parameter_names(self) -> tuple:
        return OPENING_PARAMETERS if self.operation == "open" else CLOSING_PARAMETERS

    def key(self) -> str:
        """Short hash of the spec and the prototype's realistic strengths (cache file name)."""
        payload = dict(dataclasses.asdict(self), effects=dict(_effects(self).to_dict())
                       if self.source == "prototype" else None)
        if not self.pair:  # the single-operation sets keep their cache names
            payload.pop("pair")
        return hashlib.sha1(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:10]


def _effects(spec: DatasetSpec):
    from ..prototypes.a import OPERATIONS, REALISTIC, UPPER, Effects

    # Strengths just below the prototype's hard limits stay valid for Effects' own checks.
    return Effects(**{name: min(REALISTIC[name] * spec.effects_scale, UPPER[name])
                      for name in REALISTIC if spec.operation in OPERATIONS[name]})


def condition_breaker(base: Breaker, spec: DatasetSpec, condition: int,
                      rng: np.random.Generator | None = None) -> Breaker:
    """The breaker of ``condition`` (0-based), with this run's friction and damping when ``rng``.

    Openings raise xO1 (so BO rises by kO·Δx·rO/J2 per step); closings raise xC0 (which enters
    only the closing geometry, so AC, BC, CC stay unchanged).
    """
    changes = {}
    if spec.pair:
        return _pair_breaker(base, spec, condition, rng)
    if spec.operation == "open":
        changes["xO1"] = base.xO1 + condition * STEP_M
    else:
        changes["xC0"] = base.xC0 + condition * STEP_M
    if rng is not None:
        fr = 1.0 + rng.uniform(-spec.friction_spread, spec.friction_spread)
        cb = 1.0 + rng.uniform(-spec.damping_spread, spec.damping_spread)
        changes["TOf" if spec.operation == "open" else "TCf"] = (
            (base.TOf if spec.operation == "open" else base.TCf) * fr)
        changes["cb"] = base.cb * cb
    return dataclasses.replace(base, **changes)


def _pair_breaker(base: Breaker, spec: DatasetSpec, condition: int, rng) -> Breaker:
    """The opening spring's nut moves the spring seat: the compression at the closed (xO1) and
    at the open (xO0) position both rise by ``condition·STEP_M``. One grease and temperature
    state: one friction factor on TOf and TCf, one damping factor on cb."""
    changes = {"xO0": base.xO0 + condition * STEP_M, "xO1": base.xO1 + condition * STEP_M}
    if rng is not None:
        fr = 1.0 + rng.uniform(-spec.friction_spread, spec.friction_spread)
        cb = 1.0 + rng.uniform(-spec.damping_spread, spec.damping_spread)
        changes.update(TOf=base.TOf * fr, TCf=base.TCf * fr, cb=base.cb * cb)
    return dataclasses.replace(base, **changes)


def pair_fit_breaker(base: Breaker, spec: DatasetSpec) -> Breaker:
    """What a pair's fits know: the design breaker (the setting is what is inferred), its CC
    range raised to ``PAIR_CC_HEADROOM`` × the top setting's design CC."""
    top = _pair_breaker(base, spec, spec.conditions - 1, None).design_parameters()["CC"]
    lo, hi = base.ranges["CC"]
    return dataclasses.replace(base, ranges=dict(base.ranges, CC=(lo, max(hi, PAIR_CC_HEADROOM * top))))


def setting_parameters(spec: DatasetSpec, base: Breaker | None = None) -> tuple:
    """The model parameters whose design value moves with the spring setting (Eq. 8/12):
    those that differ between the designs of condition 0 and condition 1 (BO for openings)."""
    base = base or load_reference()
    p0 = model_parameters(condition_breaker(base, spec, 0), spec.operation)
    p1 = model_parameters(condition_breaker(base, spec, 1), spec.operation)
    return tuple(k for k in spec.parameter_names if not np.isclose(p0[k], p1[k], rtol=1e-9, atol=0))


def bo_step(base: Breaker) -> float:
    """Theoretical rise of BO per condition, kO·Δx·rO/J2 [s^-2]."""
    return base.kO * STEP_M * base.rO / base.J2


def model_parameters(breaker: Breaker, operation: str) -> dict:
    """Design parameters the simulator takes for ``operation`` (closings carry DC = AO)."""
    p = breaker.design_parameters()
    names = OPENING_PARAMETERS if operation == "open" else CLOSING_PARAMETERS + ("DC",)
    return {k: p[k] for k in names}


def _with_end_of_travel(simulate):
    """Give an overdamped opening an end of travel: the first instant after buffer engagement
    at which the speed falls below 1 % of its peak. Without a rebound the prototype reports no
    velocity zero (t_peak NaN), and ``synthesize_capture`` needs one to size the capture."""
    def wrapped(params, t):
        tr = simulate(params, t)
        if np.isfinite(tr.t_peak) or not tr.success:
            return tr
        t_buf = tr.events.get("buffer_engaged", np.nan)
        speed = np.abs(tr.omega)
        slow = np.nonzero((tr.t > t_buf) & (speed < 0.01 * np.nanmax(speed)))[0]
        return dataclasses.replace(tr, t_peak=float(tr.t[slow[0]])) if slow.size else tr
    return wrapped


NUISANCE_NAMES = ("trigger_delay_s", "offset_rad", "gain", "friction_factor", "damping_factor",
                  "snr_db", "noise_rad", "gain_measured")


def unit_breaker(base: Breaker, spec: DatasetSpec) -> Breaker:
    """The true constants of ``spec.unit``: the reference itself for unit 1, else a draw of
    kO, J2, cb (each ±``tolerance``) and α0 (±``alpha0_tolerance_rad``) around the design."""
    if spec.unit == 1:
        return base
    rng = np.random.default_rng([spec.seed, 7919, spec.unit])  # 7919: the unit stream's tag
    tol = spec.tolerance
    return dataclasses.replace(
        base, kO=base.kO * (1 + rng.uniform(-tol, tol)), J2=base.J2 * (1 + rng.uniform(-tol, tol)),
        cb=base.cb * (1 + rng.uniform(-tol, tol)),
        alpha0=base.alpha0 + rng.uniform(-spec.alpha0_tolerance_rad, spec.alpha0_tolerance_rad))


def draw_recording(spec: DatasetSpec, condition: int, index: int, noise_for) -> dict:
    """This capture's trigger delay [s], sensor offset [rad], gain [-], SNR [dB] and noise [rad].

    A stream of its own (not the breaker's), so switching the field nuisance on leaves the
    breaker spread and the simulation of every capture unchanged.
    """
    rng = np.random.default_rng([spec.seed, condition, index, 0 if spec.operation == "open" else 1,
                                 spec.unit, 104729])  # 104729: the recording stream's tag
    delay = float(rng.uniform(*spec.trigger_delay_s)) if spec.trigger_delay_s else 0.02
    # One transducer records both halves of a pair minutes apart: one zero offset, one gain.
    sensor = (np.random.default_rng([spec.seed, condition, index, spec.unit, 104729, 2])
              if spec.pair else rng)
    offset = float(sensor.uniform(-spec.offset_rad, spec.offset_rad))
    gain = float(1.0 + sensor.uniform(-spec.gain_spread, spec.gain_spread))
    if spec.snr_db_range:
        snr = float(rng.uniform(*spec.snr_db_range))
        noise = noise_for(snr)
    else:
        noise, snr = spec.noise_rad, float("nan")
    return {"trigger_delay_s": delay, "offset_rad": offset, "gain": gain, "snr_db": snr,
            "noise_rad": noise, "rng": rng}


def make_capture(spec: DatasetSpec, condition: int, index: int, *, base: Breaker | None = None,
                 details: bool = False):
    """One recorded operation of ``condition`` (0-based), run ``index``: the seam of the studies.

    Returns
    -------
    capture : Capture
    truth : dict
        The model parameters the simulator was given (this unit's constants for this run).
    breaker : Breaker
        This condition's breaker as the operator knows it: the *design* values with the
        pre-compression set (no run spread, no unit tolerance), which the fit uses.
    nuisance : dict
        Only with ``details``: the drawn values named in :data:`NUISANCE_NAMES`.
    """
    base = base or load_reference()
    unit = unit_breaker(base, spec)
    if spec.unit == 1:  # the seed sequence the clean datasets have always used
        rng = np.random.default_rng([spec.seed, condition, index, 0 if spec.operation == "open" else 1])
    else:
        rng = np.random.default_rng([spec.seed, condition, index, 0 if spec.operation == "open" else 1,
                                     spec.unit])
    if spec.pair:  # the state both halves of the pair share (tag: the pair stream's)
        state = np.random.default_rng([spec.seed, condition, index, spec.unit, 15485863])
        run = condition_breaker(unit, spec, condition, state)
    else:
        run = condition_breaker(unit, spec, condition, rng)
    params = model_parameters(run, spec.operation)
    simulate = None
    if spec.source == "prototype":
        from ..prototypes.a import make_prototype_simulator

        simulate = _with_end_of_travel(
            make_prototype_simulator(run, _effects(spec), spec.operation, method="fast"))
    elif spec.source != "reduced":
        raise ValueError(f"source must be 'prototype' or 'reduced', got {spec.source!r}")
    lead = 0.4e-3 + (rng.uniform(-spec.onset_jitter_s, spec.onset_jitter_s) if spec.onset_jitter_s else 0.0)
    friction = (run.TOf / unit.TOf) if spec.operation == "open" else (run.TCf / unit.TCf)
    nuisance = {"friction_factor": float(friction), "damping_factor": float(run.cb / unit.cb)}
    if not spec.field_nuisance:
        cap, _ = synthesize_capture(run, spec.operation, params, rng=rng, noise_rad=spec.noise_rad,
                                    simulate=simulate, shock_lead_s=lead)
        nuisance.update(trigger_delay_s=0.02, offset_rad=0.0, gain=1.0, snr_db=float("nan"),
                        noise_rad=spec.noise_rad)
    else:
        rec = draw_recording(spec, condition, index, lambda snr: noise_for_snr(snr, spec))
        cap, _ = synthesize_capture(run, spec.operation, params, rng=rng, noise_rad=0.0, bits=None,
                                    simulate=simulate, shock_lead_s=lead, pre_s=rec["trigger_delay_s"])
        cap = _record(cap, rec)
        nuisance.update({k: rec[k] for k in ("trigger_delay_s", "offset_rad", "gain", "snr_db", "noise_rad")})
    out = (cap, params, pair_fit_breaker(base, spec) if spec.pair else condition_breaker(base, spec, condition))
    return out + (nuisance,) if details else out


def _record(cap, rec, bits: int = 16):
    """The sensor and the DAQ: gain and zero offset, Gaussian noise, 16-bit codes over 0..π.

    No clipping at 0: a mounting offset of a few mrad stays inside the converter's margin.
    """
    travel = rec["gain"] * np.asarray(cap.travel, float) + rec["offset_rad"]
    travel = travel + rec["rng"].normal(0.0, rec["noise_rad"], size=travel.size)
    lsb = np.pi / (2**bits - 1)
    return dataclasses.replace(cap, travel=np.round(travel / lsb) * lsb)


def zero_on_idle(capture, breaker: Breaker, operation: str):
    """The capture with its travel referred to the closed (open) stop: minus the median of the
    idle samples before the latch shock (the mechanism rests on its stop there, so any non-zero
    reading is the sensor's zero offset). Unchanged when no idle part is found."""
    from ..estimation.window import prepare_window

    try:
        w = prepare_window(capture, breaker, operation)
    except FitError:
        return capture
    i = int(round(w.t_start * capture.sample_rate))
    if i < 32:
        return capture
    travel = np.asarray(capture.travel, float)
    rest = 0.0 if operation == "open" else breaker.stroke
    return dataclasses.replace(capture, travel=travel - (np.median(travel[:i]) - rest))


def stop_to_stop_gain(capture, breaker: Breaker) -> float:
    """The sensor gain a closing measures [-]: its travel runs from the open stop (``stroke``)
    to the closed stop (0), so the span between the idle samples before the motion and the
    settled last ``SETTLED_S`` is gain × stroke. NaN when the record has no idle part."""
    from ..estimation.window import prepare_window

    try:
        w = prepare_window(capture, breaker, "close")
    except FitError:
        return float("nan")
    travel = np.asarray(capture.travel, float)
    i, n_end = int(round(w.t_start * capture.sample_rate)), int(round(SETTLED_S * capture.sample_rate))
    if i < 32 or travel.size < i + n_end:
        return float("nan")
    return float((np.median(travel[:i]) - np.median(travel[-n_end:])) / breaker.stroke)


def calibrate_gain(capture, breaker: Breaker, operation: str, gain: float):
    """The zeroed capture (:func:`zero_on_idle`) divided by the sensor ``gain`` about its rest."""
    cap = zero_on_idle(capture, breaker, operation)
    if not np.isfinite(gain) or gain <= 0:
        return cap
    rest = 0.0 if operation == "open" else breaker.stroke
    return dataclasses.replace(cap, travel=rest + (np.asarray(cap.travel, float) - rest) / gain)


def travel_features(capture, *, window_s: float = FEATURE_WINDOW_S, points: int = FEATURE_POINTS):
    """The baselines' input: raw travel [rad] over a fixed window from the first sample,
    block-averaged to ``points`` values (captures shorter than the window are padded with
    their last sample)."""
    n = int(round(window_s * capture.sample_rate))
    y = np.asarray(capture.travel, dtype=float)[:n]
    if y.size < n:
        y = np.concatenate([y, np.full(n - y.size, y[-1])])
    edges = np.linspace(0, n, points + 1).astype(int)
    return np.add.reduceat(y, edges[:-1]) / np.diff(edges)


def feature_window_s(spec: DatasetSpec) -> float:
    """The baselines' window [s]: the latest motion onset plus the whole opening (65 ms)."""
    latest = spec.trigger_delay_s[1] if spec.trigger_delay_s else 0.02
    return FEATURE_WINDOW_S + (latest - 0.02)


def _fit_task(task):
    spec, condition, index = task
    names = spec.parameter_names
    cap, truth, breaker, nuisance = make_capture(spec, condition, index, details=True)
    features = travel_features(cap, window_s=feature_window_s(spec))
    try:
        if spec.pair:  # both halves scaled by the gain the pair's closing measures stop to stop
            closing = cap if spec.operation == "close" else make_capture(
                dataclasses.replace(spec, operation="close"), condition, index)[0]
            nuisance["gain_measured"] = stop_to_stop_gain(closing, breaker)
            cap = calibrate_gain(cap, breaker, spec.operation, nuisance["gain_measured"])
        elif spec.field_nuisance:
            cap = zero_on_idle(cap, breaker, spec.operation)
        dc = None
        if spec.operation == "close":  # a pair's closing knows only the design's DC = AO
            dc = breaker.design_parameters()["DC"] if spec.pair else truth.get("DC")
        res = fit_capture(cap, breaker, spec.operation, dc=dc, seed=1 + index)
        est = [res.parameters[k] for k in names]
        err = [res.stderr[k] for k in names]
        rmse, msg = res.rmse_rad, ""
    except FitError as exc:
        est, err, rmse, msg = [np.nan] * len(names), [np.nan] * len(names), np.nan, str(exc)
    return (condition, index, est, err, [truth[k] for k in names], rmse, features, msg,
            [nuisance.get(k, np.nan) for k in NUISANCE_NAMES])


def build_dataset(spec: DatasetSpec, cache_dir: Path | None = None, *,
                  workers: int = DEFAULT_WORKERS) -> dict:
    """Fit every capture of ``spec`` (or load the cache ``<cache_dir>/dataset-<op>-<key>.npz``).

    Returns
    -------
    dict of arrays
        ``condition`` (n,), ``index`` (n,), ``estimates`` (n, p), ``stderr`` (n, p),
        ``truth`` (n, p), ``rmse_rad`` (n,), ``features`` (n, FEATURE_POINTS) [rad],
        ``errors`` (n,) fit-failure messages ('' when fitted), ``names`` (p,), ``nuisance``
        (n, 8) the drawn recording and run values named in ``nuisance_names`` (``gain_measured``:
        the stop-to-stop gain of a pair's closing, NaN outside pairs).
        A failed fit leaves NaN estimates.
    """
    path = None
    if cache_dir is not None:
        path = Path(cache_dir) / f"dataset-{spec.operation}-{spec.key()}.npz"
        if path.exists():
            with np.load(path, allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
    tasks = [(spec, c, i) for c in range(spec.conditions) for i in range(spec.per_condition)]
    rows = pool_map(_fit_task, tasks, workers)
    data = {
        "condition": np.array([r[0] for r in rows], dtype=int),
        "index": np.array([r[1] for r in rows], dtype=int),
        "estimates": np.array([r[2] for r in rows], dtype=float),
        "stderr": np.array([r[3] for r in rows], dtype=float),
        "truth": np.array([r[4] for r in rows], dtype=float),
        "rmse_rad": np.array([r[5] for r in rows], dtype=float),
        "features": np.array([r[6] for r in rows], dtype=float),
        "errors": np.array([r[7] for r in rows], dtype=str),
        "names": np.array(spec.parameter_names, dtype=str),
        "nuisance": np.array([r[8] for r in rows], dtype=float),
        "nuisance_names": np.array(NUISANCE_NAMES, dtype=str),
    }
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **data)
    return data


def snr_db(noise_rad: float, spec: DatasetSpec | None = None) -> float:
    """Signal-to-noise ratio [dB] of a travel noise: 20·log10(RMS travel / noise), the RMS taken
    over the valid interval of the noise-free nominal operation (condition 0)."""
    return 20.0 * np.log10(signal_rms(spec or DatasetSpec()) / noise_rad)


def noise_for_snr(snr: float, spec: DatasetSpec | None = None) -> float:
    """Travel noise [rad] giving ``snr`` [dB] (inverse of :func:`snr_db`)."""
    return signal_rms(spec or DatasetSpec()) * 10.0 ** (-snr / 20.0)


@lru_cache(maxsize=16)
def signal_rms(spec: DatasetSpec) -> float:
    """RMS travel [rad] over the valid interval of the noise-free nominal operation (the
    design unit, condition 0, no recording nuisance)."""
    clean = dataclasses.replace(spec, noise_rad=0.0, friction_spread=0.0, damping_spread=0.0,
                                onset_jitter_s=0.0, trigger_delay_s=None, offset_rad=0.0,
                                gain_spread=0.0, snr_db_range=None, unit=1)
    cap, _, _ = make_capture(clean, 0, 0)
    travel = np.asarray(cap.travel)
    moving = travel[int(0.02 * cap.sample_rate):]  # after synthesize_capture's 20 ms idle lead
    return float(np.sqrt(np.mean(moving**2)))
