"""Operations in a record without a vibration channel (a breaker analyser's timing test):
found from the travel, with the command instant from the coil currents.

An analyser record holds one or more operations (O, C, CO, O–CO) sampled at 5–40 kS/s, the
coil currents, and no accelerometer. An operation is a passage of the smoothed travel from one
rest zone to the other (closed: below ``ZONE`` of the stroke; open: above ``1 − ZONE``). Its
motion starts where the travel last sat within ``DEPART`` of the stroke of its rest level; its
command is the latest rise of a coil current before that, within ``COIL_TO_MOTION_MAX_S``. The
coil's rise plays the latch shock's role: the window starts there and the fit estimates the
onset delay (coil-to-motion time) itself.
"""

from __future__ import annotations

from dataclasses import replace
from datetime import timedelta

import numpy as np

from drivers.capture import Capture
from drivers.capture_file import OVER_RANGE_FLAG, over_range_flag
from drivers.masked import cut

from .operation_end import moving_average
from .trigger import CLOSE, OPEN, DetectedOperation, TriggerSettings

ZONE = 0.2        # rest zones: within 20 % of the stroke of either end
DEPART = 0.02     # motion starts where the travel leaves its rest level by 2 % of the stroke
# A coil counts as energised above 10 % of its range: the current of a DC coil rises within
# about a millisecond to that level, long before the armature moves.
COIL_LEVEL = 0.10
# Coil-to-motion times of spring-operated HV breakers are tens of ms: makers' data sheets give
# opening times of about 15–60 ms and closing times of about 40–150 ms (the times as IEC
# 62271-100 defines them, command to contact separation/touch); 0.25 s bounds the search with
# room for slow mechanisms.
COIL_TO_MOTION_MAX_S = 0.25
COMMAND_FROM_COIL = "command_from_coil"
NO_COIL_COMMAND = "no_coil_command"


def detect_from_coils(capture: Capture, settings: TriggerSettings) -> list[DetectedOperation]:
    """Every operation of ``capture`` (travel [rad from closed]) in time order, each with its
    own capture cut from the previous operation's end to the next one's command."""
    fs = float(capture.sample_rate)
    stroke = float(settings.stroke_rad)
    T = np.asarray(capture.travel, dtype=float)
    S = moving_average(T, max(int(1e-3 * fs), 1))
    zone = np.where(S < ZONE * stroke, -1, np.where(S > (1 - ZONE) * stroke, 1, 0))
    idx = np.flatnonzero(zone)
    if idx.size == 0:
        return []
    z = zone[idx]
    changes = np.flatnonzero(np.diff(z) != 0)
    coils = _coil_rises(capture)
    events = []
    prev_entry = 0
    for c in changes:
        leave, enter = int(idx[c]), int(idx[c + 1])  # last sample in the old zone, first in the new
        operation = OPEN if z[c + 1] == 1 else CLOSE
        level = float(np.median(S[prev_entry: leave + 1]))
        near = np.flatnonzero(np.abs(S[prev_entry: leave + 1] - level) <= DEPART * stroke)
        depart = prev_entry + int(near[-1]) if near.size else leave
        events.append([operation, depart, enter])
        prev_entry = enter
    ops = []
    first = int(capture.first_sample_index)
    for k, (operation, depart, enter) in enumerate(events):
        stop = events[k + 1][1] if k + 1 < len(events) else T.size
        y = S if operation == OPEN else stroke - S
        seg = y[enter: stop]
        if operation == OPEN:
            end = enter + int(np.argmax(seg))
        else:
            top = float(np.max(seg))
            end = enter + int(np.flatnonzero(seg >= top - 0.01 * stroke)[0])
        lo_bound = ops[-1][3] if ops else 0  # previous operation's end
        cmd, names = _command(coils, depart, max(lo_bound, depart - int(COIL_TO_MOTION_MAX_S * fs)),
                              max(int(5e-3 * fs), 1))
        ops.append((operation, depart, cmd, end, names))
    out = []
    for k, (operation, depart, cmd, end, names) in enumerate(ops):
        start_ref = cmd if cmd is not None else depart
        a = max(start_ref - int(settings.pre_trigger_s * fs), ops[k - 1][3] if k else 0, 0)
        nxt = ops[k + 1] if k + 1 < len(ops) else None
        b = T.size if nxt is None else max(min(end + int(max(settings.post_s, 0.05) * fs),
                                               (nxt[2] if nxt[2] is not None else nxt[1]) - 1), end + 1)
        meta = {**capture.meta, "operation": operation, "motion_s": (depart - a) / fs,
                "index_in_record": k}
        if cmd is not None:
            meta.update(command_s=(cmd - a) / fs, command_source="coil " + "/".join(names))
        kept = tuple(f for f in capture.flags if not f.startswith(OVER_RANGE_FLAG))
        if capture.meta.get("masked") is not None:  # the over-range spans inside this cut only
            meta["masked"] = cut(capture.meta["masked"], a, b, fs)
            kept += (over_range_flag(meta["masked"]),) if meta["masked"] else ()
        sub = Capture(travel=T[a:b].copy(), sample_rate=fs, vibration=None, source=capture.source,
                      flags=kept, first_sample_index=first + a, travel_limits=capture.travel_limits, meta=meta,
                      start_time=None if capture.start_time is None
                      else capture.start_time + timedelta(seconds=a / fs),
                      aux=tuple(replace(x, data=x.data[a:b].copy()) for x in capture.aux))
        start = cmd if cmd is not None else depart
        flags = (COMMAND_FROM_COIL,) if cmd is not None else (NO_COIL_COMMAND,)
        out.append(DetectedOperation(operation=operation, shock_index=first + start,
                                     window_start_index=float(first + start), window_end_index=float(first + end),
                                     sample_rate=fs, flags=flags, capture=sub))
    return out


def _coil_rises(capture: Capture) -> list:
    """(name, rise indices) of each coil current: upward crossings of ``COIL_LEVEL`` of its
    range (a coil already energised at the first sample rises there)."""
    out = []
    for ch in capture.aux_of("coil_current"):
        x = np.asarray(ch.data, dtype=float)
        ok = np.isfinite(x)
        if ok.sum() < 16:
            continue  # no coil current to read (a NaN or over-range channel throughout)
        # a NaN or infinite sample is no reading: the levels come from the finite ones, and the
        # last reading before it stands in for it (so it neither starts nor ends a pulse)
        held = np.maximum.accumulate(np.where(ok, np.arange(x.size), -1))
        x = x[np.where(held >= 0, held, int(np.argmax(ok)))]
        lo, hi = np.percentile(x, 1), np.percentile(x, 99.5)
        # Sample-to-sample noise (robust to the steps themselves): a coil that is never
        # energised spans a few noise sd; one that is, hundreds. 20 sd keeps noise out.
        noise = 1.4826 * float(np.median(np.abs(np.diff(x)))) / np.sqrt(2.0)
        if hi - lo <= max(20.0 * noise, 0.0) or hi - lo <= 0:
            continue
        on = moving_average(x, max(int(2e-4 * capture.sample_rate), 1)) > lo + COIL_LEVEL * (hi - lo)
        rises = np.flatnonzero(on[1:] & ~on[:-1]) + 1
        if on[0]:
            rises = np.concatenate([[0], rises])
        out.append((ch.name, rises))
    return out


def _command(coils, depart: int, earliest: int, group_n: int):
    """The latest coil rise in [earliest, depart], and the coils rising with it (within
    ``group_n`` samples: parallel coils of one command); the earliest of those is the command."""
    best = None
    for _, rises in coils:
        r = rises[(rises >= earliest) & (rises <= depart)]
        if r.size and (best is None or r[-1] > best):
            best = int(r[-1])
    if best is None:
        return None, []
    group, names = [], []
    for name, rises in coils:
        r = rises[(rises >= earliest) & (rises <= depart) & (np.abs(rises - best) <= group_n)]
        if r.size:
            group.append(int(r[-1]))
            names.append(name)
    return min(group), names
