"""The corpus's labels, from the oracle alone (issue 48 item 1).

A group's label is the hypothesis a right answer names: ``none``, an effect, a pair ``a+b``
(sorted), or ``unexplained``. It is read from the generator's truth and the oracle's figures
(``oracle``: Δχ² of the exact curves over the reduced fit; ≥ ``DETECTABLE`` = 100 detectable),
never from the diagnosis:

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

DETECTABLE = 100.0
SENSOR = "sensor_nonlinearity"


def label(row: dict) -> tuple:
    """(label or None, reason) of a corpus row (module docstring)."""
    o = row.get("oracle") or {}
    if not o or "error" in o:
        return None, f"no oracle: {o.get('error', 'not run')}"
    if o.get("failed_fits"):
        return None, f"the oracle's reduced fit failed on capture(s) {o['failed_fits']}"
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
