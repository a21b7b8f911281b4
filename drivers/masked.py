"""Masked samples: the spans of a channel an instrument marked over-range (``∞``, ``NaN``...).

An analyser writes an over-range sample as a word, not a number; the sample is missing, the
rest of the channel is good. A span is a run of consecutive masked samples; it travels with
the capture as JSON (``Capture.meta["masked"]``) and is cut with it, so the stored record, the
page and the fit all name the same samples. Pure: no I/O.
"""

from __future__ import annotations

import numpy as np


def runs(mask) -> list[tuple[int, int]]:
    """``[(first, last), ...]`` sample indices (inclusive) of each run of True in ``mask``."""
    m = np.asarray(mask, dtype=bool)
    if not m.any():
        return []
    d = np.diff(np.concatenate([[0], m.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    return [(int(a), int(b)) for a, b in zip(starts, stops)]


def spans(channel: str, mask, sample_rate: float | None) -> list[dict]:
    """The masked spans of one channel as JSON: ``channel``, ``first_index``, ``last_index``,
    ``count`` and, when the rate is known, ``first_s`` and ``last_s`` [s from the first sample]."""
    out = []
    for a, b in runs(mask):
        row = {"channel": channel, "first_index": a, "last_index": b, "count": b - a + 1}
        if sample_rate:
            row.update(first_s=a / sample_rate, last_s=b / sample_rate)
        out.append(row)
    return out


def filled(x, mask) -> np.ndarray:
    """``x`` with its masked samples replaced by the straight line between the valid neighbours
    (held flat at the ends), so that a file format or a filter without NaN can carry the channel;
    the spans themselves say which samples are not measured."""
    x = np.array(x, dtype=float)
    m = np.asarray(mask, dtype=bool)
    if m.any() and not m.all():
        i = np.arange(x.size)
        x[m] = np.interp(i[m], i[~m], x[~m])
    return x


def cut(masked: list, first: int, stop: int, sample_rate: float) -> list[dict]:
    """The spans of ``masked`` inside samples ``[first, stop)``, re-indexed from ``first``."""
    out = []
    for s in masked or []:
        a, b = max(int(s["first_index"]), first), min(int(s["last_index"]), stop - 1)
        if a > b:
            continue
        row = dict(s, first_index=a - first, last_index=b - first, count=b - a + 1)
        row.update(first_s=(a - first) / sample_rate, last_s=(b - first) / sample_rate)
        out.append(row)
    return out


def overlapping(masked: list, channel: str, first: int, last: int) -> list[dict]:
    """The spans of ``channel`` that touch samples ``first..last`` (inclusive)."""
    return [s for s in masked or [] if s.get("channel") == channel
            and int(s["first_index"]) <= last and int(s["last_index"]) >= first]


def describe(s: dict) -> str:
    """One span in words: ``T1: 12 samples, 312.40–313.50 ms``."""
    where = (f"{1e3 * s['first_s']:.2f}–{1e3 * s['last_s']:.2f} ms" if "first_s" in s
             else f"samples {s['first_index']}–{s['last_index']}")
    return f"{s['channel']}: {s['count']} sample{'s' if s['count'] != 1 else ''}, {where}"


__all__ = ["cut", "describe", "filled", "overlapping", "runs", "spans"]
