"""Where an operation ends in the trigger's stream segment: the opening's travel maximum and
the closing's end of the cam rise. Pure functions of the segment (travel ``T``, valid mask
``M``, smoothed travel ``S``; indices are segment sample indices)."""

from __future__ import annotations

import numpy as np


def moving_average(x: np.ndarray, w: int) -> np.ndarray:
    """Centred moving average of length ``w``; the ends use the nearest full window."""
    if w <= 1 or x.size < w:
        return x.astype(float, copy=True)
    c = np.concatenate(([0.0], np.cumsum(x, dtype=float)))
    core = (c[w:] - c[:-w]) / w
    left = (w - 1) // 2
    return np.concatenate((np.full(left, core[0]), core, np.full(x.size - core.size - left, core[-1])))


def opening_end(T, M, S, r: int, settings, fs: float):
    """Peak of the opening travel [fractional segment index] by a local cubic fit."""
    s = settings

    def n(seconds):
        return int(round(seconds * fs))

    wide = moving_average(T, max(1, n(1e-3)))
    stop = min(S.size, r + n(s.max_operation_s))
    # Stop the search where the travel falls back by the motion threshold (a new operation).
    fall = np.maximum.accumulate(wide[r:stop]) - wide[r:stop]
    back = np.flatnonzero(fall > s.motion_fraction * s.stroke_rad)
    if back.size:
        stop = r + int(back[0])
    p0 = r + int(np.argmax(wide[r:stop]))
    return _fit_peak(T, M, p0, n(s.peak_half_window_s))


def closing_end(T, M, S, r: int, settings, fs: float):
    """End of the cam rise [fractional segment index]: where the travel's approach to the
    settled closed level ends, from a fit y = a·u² + b·u³ with u = max(t_e − t, 0)."""
    s = settings

    def n(seconds):
        return int(round(seconds * fs))

    settle_n = n(s.settle_s)
    tol = s.settle_fraction * s.stroke_rad
    if S.size <= r + settle_n:
        return float(r), False
    change = np.abs(S[r:-settle_n] - S[r + settle_n:])
    q = r + int(np.argmax(change < tol))
    tail = slice(q, min(S.size, q + 2 * settle_n))
    level = float(np.median(T[tail][M[tail]])) if M[tail].any() else float(S[q])
    # Fit from where the travel was still closing_fit_fraction of the stroke above the level.
    i0 = r - int(np.argmax(S[r::-1] - level >= s.closing_fit_fraction * s.stroke_rad))
    i1 = min(T.size, q + 3 * settle_n)
    keep = M[i0:i1]
    t = np.arange(i0, i1, dtype=float)[keep]
    y = T[i0:i1][keep] - level
    if t.size < 16:
        return float(q), False
    # Coarse-to-fine search of t_e: 0.25 ms steps on every 4th sample, then finer.
    step = max(4.0, round(0.25e-3 * fs))
    grid = np.arange(i0, i1, step)
    te = grid[np.argmin(_tangent_fit_sse(t[::4], y[::4], grid))]
    for half, fine in ((step, step / 8), (step / 8, 0.5)):
        grid = np.arange(te - half, te + half + 1e-9, fine)
        te = grid[np.argmin(_tangent_fit_sse(t, y, grid))]
    return float(te), True


def _fit_peak(T, M, p0: int, half: int):
    """Maximum of a cubic least-squares fit to the travel within ±``half`` samples of ``p0``,
    re-centred once on the result. Returns (fractional index, fit succeeded)."""
    ok = False
    peak = float(p0)
    for _ in range(3):
        lo, hi = max(0, p0 - half), min(T.size, p0 + half + 1)
        keep = M[lo:hi]
        if keep.sum() < 16:
            return peak, ok
        x = (np.arange(lo, hi)[keep] - p0) / half
        c = np.polynomial.polynomial.polyfit(x, T[lo:hi][keep], 3)
        roots = np.roots([3 * c[3], 2 * c[2], c[1]]) if abs(c[3]) > 1e-12 else (
            np.array([-c[1] / (2 * c[2])]) if c[2] else np.empty(0))
        roots = [float(z.real) for z in np.atleast_1d(roots)
                 if abs(z.imag) < 1e-12 and abs(z.real) <= 1.0 and 2 * c[2] + 6 * c[3] * z.real < 0]
        if not roots:
            return peak, ok
        x_peak = min(roots, key=abs)
        peak, ok = p0 + x_peak * half, True
        if abs(x_peak * half) < 1.0:
            break
        p0 = int(round(peak))
    return peak, ok


def _tangent_fit_sse(t: np.ndarray, y: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """Residual sum of squares of y ≈ a·u² + b·u³, u = max(t_e − t, 0), for each candidate t_e.

    The travel arrives tangentially at the closed level (the cam rise ends with zero slope),
    hence no constant or linear term.
    """
    u = np.maximum(candidates[:, None] - t[None, :], 0.0) / 128.0  # scaled for conditioning
    u2 = u * u
    u3 = u2 * u
    s44, s45, s55 = (u2 * u2).sum(1), (u2 * u3).sum(1), (u3 * u3).sum(1)
    r2, r3 = u2 @ y, u3 @ y
    det = s44 * s55 - s45 * s45
    safe = np.where(np.abs(det) > 1e-300, det, np.inf)
    a = (r2 * s55 - r3 * s45) / safe
    b = (s44 * r3 - s45 * r2) / safe
    return float(y @ y) - (a * r2 + b * r3)
