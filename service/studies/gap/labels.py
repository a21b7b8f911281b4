"""The corpus's labels, from the oracle alone (issue 48 item 1).

A group's label is the hypothesis a right answer names: ``none``, an effect, a pair ``a+b``
(sorted), or ``unexplained``. It is read from the generator's truth and the oracle's figures
(``oracle``: Δχ² of the exact curves over the reduced fit), never from the diagnosis.

Detectable (issue 54 item 2): a Δχ² is detectable when it is at least ``threshold(row)``, the
noncentrality at which the diagnosis's own test of ``none`` (``diagnosis.none_test``: the gap's
χ² on df = the group's spline degrees of freedom, at its designed level 0.01) refuses ``none``
half the time: the λ with P(χ²'(df, λ) > χ²_{0.99}(df)) = 0.5 (≈ 44 for 5 captures, df ≈ 150;
≈ 35 for 3, df ≈ 90), so the threshold grows with the group's size as the χ² law says. A row
without the test's df (written before it) keeps the former fixed ``DETECTABLE`` = 100, and its
reason says so. The rules:

1. **Failed oracle fits.** A group whose oracle reduced fit failed even after the retries
   (``oracle.reduced_fit``) has no label: ``None`` with the reason (counted, never scored).
2. **The prototype's own gap.** When the healthy twin of the group (the same unit without its
   effects, the same noise) is itself detectable (``healthy_delta_chi2`` ≥ 100: the reduced
   model misses this prototype without any effect, as on E), the gap holds something no
   catalogued effect is: ``unexplained``.
3. **The effects.** Outside the catalogue and detectable: ``unexplained``; detectable single
   effect: its name; detectable pair: the pair; an undetectable group: ``none``.
4. **The sensor's bow.** Read through a sensor whose nonlinearity (the lever's bow, the crank's
   form) is detectable on its own (``bow_delta_chi2`` ≥ 100: the exact reading without the bow,
   its zero and gain refitted, against the exact reading with it), ``sensor_nonlinearity`` is
   part of the truth: ``none`` becomes ``sensor_nonlinearity``, an effect ``e`` the pair
   ``e+sensor_nonlinearity``; beside a pair (three effects, which no hypothesis holds) or an
   effect outside the catalogue the label is ``unexplained``.
"""

from __future__ import annotations

import numpy as np

DETECTABLE = 100.0          # the former fixed threshold (rows without the test's df)
DETECT_POWER = 0.5          # detectable: the none test refuses none at least half the time
SENSOR = "sensor_nonlinearity"


def threshold(row: dict) -> tuple[float, str]:
    """(the Δχ² a gap needs to be detectable on this row's group, how it was derived)."""
    from scipy.optimize import brentq
    from scipy.stats import chi2, ncx2

    from ...diagnosis.none_test import LEVEL

    nt = row.get("none_test") or {}
    df = int(nt.get("df_gap") or 0)
    if df <= 0:
        return DETECTABLE, "the former fixed threshold 100 (no none test on this row)"
    c = chi2.isf(LEVEL, df)
    lam = brentq(lambda x: ncx2.sf(c, df, x) - DETECT_POWER, 1e-9, 1e6)
    return float(lam), f"threshold {lam:.0f}: the none test's power {DETECT_POWER} at level {LEVEL} on df {df}"


def label(row: dict) -> tuple:
    """(label or None, reason) of a corpus row (module docstring)."""
    lab, why = _label(row)
    return lab, (f"{why}; {threshold(row)[1]}" if lab is not None else why)


def _label(row: dict) -> tuple:
    o = row.get("oracle") or {}
    if not o or "error" in o:
        return None, f"no oracle: {o.get('error', 'not run')}"
    if o.get("failed_fits"):
        return None, f"the oracle's reduced fit failed on capture(s) {o['failed_fits']}"
    DETECTABLE = threshold(row)[0]    # noqa: N806 (the row's own, shadowing the former constant)
    delta = float(o.get("delta_chi2_subset", o.get("delta_chi2", 0.0)))
    twin = o.get("healthy_delta_chi2_subset", o.get("healthy_delta_chi2"))
    bow = float(row.get("bow_delta_chi2") or 0.0) >= DETECTABLE
    truth = sorted(row.get("truth") or [])
    if twin is not None and float(twin) >= DETECTABLE:
        return "unexplained", f"the healthy twin's own gap Δχ² {float(twin):.0f}"
    if row.get("outside"):
        base = "unexplained" if delta >= DETECTABLE else "none"
    elif not truth or delta < DETECTABLE:
        base = "none"
    else:
        base = "+".join(truth)
    if not bow:
        return base, f"oracle Δχ² {delta:.0f}"
    if base == "none":
        return SENSOR, f"the sensor's bow alone (Δχ² {float(row['bow_delta_chi2']):.0f})"
    parts = base.split("+")
    if base == "unexplained" or len(parts) == 2:
        return ("+".join(parts) if SENSOR in parts else "unexplained"), "with the sensor's bow"
    return "+".join(sorted(set(parts) | {SENSOR})), "with the sensor's bow"


def bow_delta_chi2(reads, cleans, sample_rate, sensors, reading) -> float:
    """Σ over captures of χ²(exact reading without the bow, zero and gain refitted) − χ²(exact
    reading with it), under the AR noise model of what the exact reading leaves (``oracle``).
    ``reading(y, fs, sensor, with_bow=...)`` is the sensor kind's own."""
    from .oracle import ar_whitener, chi2

    total = 0.0
    for y, clean, fs, s in zip(reads, cleans, sample_rate, sensors):
        y = np.asarray(y, float)
        with_b = reading(clean, fs, s, with_bow=True)
        without = reading(clean, fs, s, with_bow=False)
        noise = y - with_b
        a, sd = ar_whitener(noise)
        A = np.column_stack([np.ones_like(without), without])
        r = y - A @ np.linalg.lstsq(A, y, rcond=None)[0]
        total += chi2(r, a, sd) - chi2(noise, a, sd)
    return float(total)
