"""Where an operation ends in the trigger's stream segment: the opening's travel maximum and
the closing's end of the cam rise. Pure functions of the segment (travel ``T``, valid mask
``M``, smoothed travel ``S``; indices are segment sample indices)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter1d, minimum_filter1d, uniform_filter1d


def moving_average(x: np.ndarray, w: int) -> np.ndarray:
    """Centred moving average of length ``w``, the ends padded with the edge sample (scipy's
    ``uniform_filter1d``, ``mode="nearest"``: the convention of every moving average in hvcb)."""
    x = np.asarray(x, dtype=float)
    if w <= 1:
        return x.copy()
    return uniform_filter1d(x, w, mode="nearest")


def opening_end(T, M, S, r: int, settings, fs: float):
    """Peak of the opening travel [fractional segment index] and whether the fit succeeded.

    The arrival at the top follows the model, but the return to rest can be much quicker (a
    critically damped return) or swing past rest: each side of the top may get its own fit
    (see ``_two_sided_peak``).
    """
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
    return _two_sided_peak(T, M, wide, p0, n(s.peak_half_window_s),
                           s.peak_fit_drop_fraction * s.stroke_rad)


MIN_SIDE = 16          # samples each side of a candidate top needs for its own fit
TWO_SIDED_EVIDENCE = 20.0  # SSE drop [noise variances] that makes the two-sided fit win


def _two_sided_peak(T, M, wide, p0: int, half: int, drop: float):
    """Top of the travel [fractional index] and whether the fit succeeded.

    The top p is searched over every 4th sample, then to a quarter sample, for two least-squares
    models in τ = t − p, both leaving the top with zero slope:

    - one cubic across the top, y = c + a·τ² + b·τ³ (the model's own smooth return);
    - one cubic per side (separate a, b before and after p), for a return much quicker than
      the arrival (critically damped) or swinging past rest.

    The two-sided model is taken when it lowers the residual by more than
    ``TWO_SIDED_EVIDENCE`` noise variances (it has two more parameters). Each side's data run
    from the top until the smoothed travel ``wide`` has fallen ``drop`` [rad] below it, at most
    ``half`` samples, so a quick return is fitted only where a cubic still follows it. The
    window is re-centred once when the result is far from where it was centred.
    """
    peak, ok, chosen = float(p0), False, None
    for _ in range(2):
        top = wide[p0]
        lo = p0 - _run_above(wide[max(0, p0 - half):p0 + 1][::-1], top - drop)
        hi = p0 + _run_above(wide[p0:min(T.size, p0 + half + 1)], top - drop) + 1
        keep = M[lo:hi]
        t = np.arange(lo, hi, dtype=float)[keep]
        if t.size < 4 * MIN_SIDE:
            return peak, ok
        fit = _PeakFit(t, T[lo:hi][keep] - top, centre=float(p0), scale=float(half))
        bounds = (t[MIN_SIDE], t[-MIN_SIDE - 1])
        one, two = fit.search(bounds)
        if two is None and one is None:
            return peak, ok
        if one is None or (two is not None and
                           one[1] - two[1] > TWO_SIDED_EVIDENCE * two[1] / max(t.size - 6, 1)):
            p, model = two[0], "two"
        else:
            p, model = one[0], "one"
        if ok and model != chosen:
            return peak, ok  # the re-centred window changed the verdict: keep the first answer
        chosen = model
        moved = abs(p - p0) > half / 16  # re-centre only when the window was clearly off
        peak, ok, p0 = float(p), True, int(round(p))
        if not moved:
            break
    return peak, ok


def _run_above(x, level) -> int:
    """Samples from the start of ``x`` before it first drops below ``level`` (all if never)."""
    below = np.flatnonzero(x < level)
    return int(below[0]) if below.size else x.size - 1


def _binomial():
    from math import comb

    return np.array([[float(comb(j, k)) if k <= j else 0.0 for k in range(7)] for j in range(7)])


class _PowerSums:
    """Moments of samples (t, y) on either side of many candidate split points at O(1) each.

    Prefix sums of u^k and u^k·y (u = (t − centre)/scale, for conditioning) give each side's
    sums of (u − q)^j and (u − q)^j·y about a candidate q by the binomial expansion, so no
    candidate touches the samples.
    """

    COMB = _binomial()  # C(j, k), zero above the diagonal
    LAG = np.maximum(np.subtract.outer(np.arange(7), np.arange(7)), 0)  # j − k

    def __init__(self, t, y, *, centre: float, scale: float):
        self.centre, self.scale = centre, scale
        self.u = (np.asarray(t, dtype=float) - centre) / scale
        self.m = self.u.size
        powers = np.empty((7, self.m))
        powers[0] = 1.0
        for k in range(1, 7):
            np.multiply(powers[k - 1], self.u, out=powers[k])
        self.P = np.concatenate([np.zeros((7, 1)), np.cumsum(powers, axis=1)], axis=1)
        self.Q = np.concatenate([np.zeros((4, 1)), np.cumsum(powers[:4] * y, axis=1)], axis=1)
        self.yy = float(y @ y)

    def _about(self, S, q, top):
        """Rows j < ``top`` of sum over k of C(j, k)·(−q)^(j−k)·S[k]: moments about q."""
        neg = np.empty((top, q.size))
        neg[0] = 1.0
        for n in range(1, top):
            np.multiply(neg[n - 1], -q, out=neg[n])
        B = self.COMB[:top, :top, None] * neg[self.LAG[:top, :top]]  # (j, k, K)
        return np.einsum("jkK,kK->jK", B, S[:top])

    def sides(self, candidates):
        """(q, ML, MR, NL, NR): candidates in u, and per side (left: u < q) the sums of
        (u − q)^j for j ≤ 6 and of (u − q)^j·y for j ≤ 3, shape (j, K)."""
        q = (np.asarray(candidates, dtype=float) - self.centre) / self.scale
        i = np.searchsorted(self.u, q, side="left")
        SL, SR = self.P[:, i], self.P[:, -1:] - self.P[:, i]
        QL, QR = self.Q[:, i], self.Q[:, -1:] - self.Q[:, i]
        return q, self._about(SL, q, 7), self._about(SR, q, 7), self._about(QL, q, 4), self._about(QR, q, 4)


class _PeakFit(_PowerSums):
    """Least-squares peak fits of samples (t, y) for many candidate tops at O(1) each."""

    def sse(self, candidates):
        """Residual sums of squares per candidate top [sample index] of the one-cubic and the
        two-sided fit; inf where the fitted curve is not highest at the candidate (it must stay
        below the top over the data)."""
        q, ML, MR, NL, NR = self.sides(candidates)
        first, last = self.u[0] - q, self.u[-1] - q
        return (self._solve(q, ML + MR, None, NL + NR, None,
                            first, last),
                self._solve(q, ML, MR, NL, NR, first, last))

    def _solve(self, q, ML, MR, NL, NR, first, last):
        """SSE of the one-cubic fit (MR None: ML, NL hold both sides) or the two-sided fit."""
        two_sided = MR is not None
        K = q.size
        n0 = np.full(K, float(self.m))
        sy = NL[0] + NR[0] if two_sided else NL[0]
        zero = np.zeros(K)
        if two_sided:
            A = np.stack([np.stack([n0, ML[2], ML[3], MR[2], MR[3]], -1),
                          np.stack([ML[2], ML[4], ML[5], zero, zero], -1),
                          np.stack([ML[3], ML[5], ML[6], zero, zero], -1),
                          np.stack([MR[2], zero, zero, MR[4], MR[5]], -1),
                          np.stack([MR[3], zero, zero, MR[5], MR[6]], -1)], 1)
            b = np.stack([sy, NL[2], NL[3], NR[2], NR[3]], -1)
        else:
            Mt, Nt = ML, NL
            A = np.stack([np.stack([n0, Mt[2], Mt[3]], -1), np.stack([Mt[2], Mt[4], Mt[5]], -1),
                          np.stack([Mt[3], Mt[5], Mt[6]], -1)], 1)
            b = np.stack([sy, Nt[2], Nt[3]], -1)
        k = b.shape[1]
        beta = np.linalg.solve(A + 1e-12 * np.eye(k), b[:, :, None])[:, :, 0]
        sse = self.yy - np.einsum("ki,ki->k", beta, b)
        a1, b1 = beta[:, 1], beta[:, 2]
        a2, b2 = (beta[:, 3], beta[:, 4]) if two_sided else (a1, b1)
        # The fitted curve τ²·(a + bτ) stays below the top when the linear factor is <= 0 at
        # both ends of each side.
        below_left = (a1 <= 0) & (a1 + b1 * first <= 0)
        below_right = (a2 <= 0) & (a2 + b2 * last <= 0)
        return np.where(below_left & below_right, sse, np.inf)

    def search(self, bounds):
        """Best top within ``bounds`` [sample index] of each model, one-cubic and two-sided:
        (p, SSE), or None when no candidate is a top. Every 4th sample, then quarter samples."""
        grid = np.arange(np.ceil(bounds[0]), bounds[1] + 1e-9, 4.0)
        if grid.size == 0:
            return None, None
        out = []
        for k, sse in enumerate(self.sse(grid)):
            if not np.isfinite(sse).any():
                out.append(None)
                continue
            p = grid[np.argmin(sse)]
            fine = np.clip(np.arange(p - 4.0, p + 4.0 + 1e-9, 0.25), *bounds)
            sse = self.sse(fine)[k]
            j = int(np.argmin(sse))
            out.append((float(fine[j]), float(sse[j])) if np.isfinite(sse[j]) else None)
        return tuple(out)


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
    # Coarse-to-fine search of t_e: 0.25 ms steps, then finer.
    fit = _PowerSums(t, y, centre=0.5 * (i0 + i1), scale=max(0.5 * (i1 - i0), 1.0))
    step = max(4.0, round(0.25e-3 * fs))
    grid = np.arange(i0, i1, step)
    te = grid[np.argmin(_tangent_fit_sse(fit, grid))]
    for half, fine in ((step, step / 8), (step / 8, 0.5)):
        grid = np.arange(te - half, te + half + 1e-9, fine)
        te = grid[np.argmin(_tangent_fit_sse(fit, grid))]
    return float(te), True


def _tangent_fit_sse(fit: "_PowerSums", candidates: np.ndarray) -> np.ndarray:
    """Residual sum of squares of y ≈ a·u² + b·u³, u = max(t_e − t, 0), for each candidate t_e.

    The travel arrives tangentially at the closed level (the cam rise ends with zero slope),
    hence no constant or linear term. Only samples before t_e carry the model: the left-side
    sums of (t − t_e)^j (the sign of the cubic term does not change the residual).
    """
    _, ML, _, NL, _ = fit.sides(candidates)
    s44, s45, s55 = ML[4], ML[5], ML[6]
    r2, r3 = NL[2], NL[3]
    det = s44 * s55 - s45 * s45
    safe = np.where(np.abs(det) > 1e-12 * np.maximum(s44 * s55, 1e-300), det, np.inf)
    a = (r2 * s55 - r3 * s45) / safe
    b = (s44 * r3 - s45 * r2) / safe
    return fit.yy - (a * r2 + b * r3)


@dataclass(frozen=True)
class Settling:
    """How the travel comes to rest after an operation's end (segment indices, rad).

    ``settled`` is the first index from which the travel stays within ``settle_fraction`` of
    the stroke for ``rest_s`` (``found`` False: not within the data, or a new operation
    started first; ``settled`` is then where the search stopped). ``rest`` is the level there
    and ``swing`` the largest distance from it between the end and ``settled``: the overtravel
    and any rebound swinging past rest.
    """

    settled: int
    rest: float
    swing: float
    found: bool


def settling(S, end: int, reach: float, settings, fs: float, limit: int) -> Settling:
    """Find where the smoothed travel ``S`` settles after ``end``, searching up to ``limit``.

    The settling stays within ``reach`` [rad] of the end level; leaving it is a new operation,
    which stops the search.
    """
    s = settings
    settle_n = max(int(round(s.rest_s * fs)), 1)
    tol = s.settle_fraction * s.stroke_rad
    end = min(max(end, 0), S.size - 1)
    out = np.flatnonzero(np.abs(S[end:limit] - S[end]) > reach)
    stop = end + int(out[0]) if out.size else min(limit, S.size)
    # S is smoothed over smoothing_s: every step-th sample keeps its range.
    step = max(1, int(s.smoothing_s * fs) // 4)
    seg = S[end:stop:step]
    w = max(settle_n // step, 1)
    found = False
    settled = stop
    if seg.size > w:
        # Range of the travel over the rest_s that follows each sample.
        spread = maximum_filter1d(seg, w, origin=-(w // 2)) - minimum_filter1d(seg, w, origin=-(w // 2))
        calm = np.flatnonzero(spread[:seg.size - w + 1] < tol)
        if calm.size:
            settled, found = end + int(calm[0]) * step, True
    tail = S[max(settled - settle_n, end):settled + settle_n] if not found else S[settled:settled + settle_n]
    rest = float(np.median(tail)) if tail.size else float(S[end])
    swing = float(np.max(np.abs(S[end:settled + 1] - rest))) if settled >= end else 0.0
    return Settling(settled, rest, swing, found)
