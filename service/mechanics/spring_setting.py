"""The opening spring's setting and the friction from a close–open pair's fitted parameters.

The nut adds the pre-load P = κ·kO·k·Δx·rO [N·m] (k nut steps of Δx from the design seat, κ
the unit's spring rate over the design's); one grease and temperature state scales both
resistance torques by one friction factor f. Eqs. 8 and 12, multiplied by J2 and divided by J1
through the closing's BC = J2/J1, are torques over J1 free of the unit's J2:

    BO·BC·J1 = κ·kO·xO1·rO + P − f·TOf        (opening)
    CC·BC·J1 = κ·kO·xO0·rO + P + f·TCf        (closing)

Two equations, so P and f follow once κ is known (determinant TOf + TCf). κ itself enters
only with P: a unit 1 % stiffer reads as :func:`steps_per_kO` × 1 % more nut steps, and no
pair can tell the two apart (the Fisher information of (k, f, κ) from BO and CC is rank 2).
AO = κ·kO·rO²/J2 carries κ, but the opening fit trades AO against BO (docs/pairs.md). So the
unit's κ comes from one pair at a known setting (a commissioning record), and a pair is read
relative to it: the constant offset of κ cancels.

Pure: numbers in, numbers out; units in the docstrings.
"""

from __future__ import annotations

import math

from .breaker import Breaker

# One nut step: two turns of the reference breaker's plate nut [m] (the paper's Table 9
# settings; service.studies.condition_data.STEP_M is the same value).
NUT_STEP_M = 3.5e-3
# A close and an open of one breaker this close in time share one friction state (docs/pairs.md).
PAIR_WINDOW_S = 15 * 60.0
Z95 = 1.959964


def step_nm(breaker: Breaker) -> float:
    """One nut step of pre-load [N·m] of the design: kO·Δx·rO."""
    return breaker.kO * NUT_STEP_M * breaker.rO


def steps_per_kO(breaker: Breaker) -> float:
    """Nut steps a unit's spring rate reads as, per unit of κ − 1 [steps]: the pair's solution
    for P weighs BO's kO·xO1·rO by TCf/(TOf + TCf) and CC's kO·xO0·rO by TOf/(TOf + TCf)."""
    b = breaker
    return (b.TCf * b.xO1 + b.TOf * b.xO0) / ((b.TOf + b.TCf) * NUT_STEP_M)


def pair_reading(breaker: Breaker, BO: float, BC: float, CC: float, *, sd: dict | None = None) -> dict:
    """The nut steps k and friction factor f a pair's fitted parameters say, for κ = 1.

    Parameters
    ----------
    breaker : Breaker
        The design (kO, xO0, xO1, rO, J1, TOf, TCf).
    BO, CC : float
        The opening's BO and the closing's CC [s^-2].
    BC : float
        The closing's BC = J2/J1 [-].
    sd : dict, optional
        Standard deviations of ``BO``, ``BC``, ``CC`` (the fits' own) [s^-2, -, s^-2].

    Returns
    -------
    dict
        ``steps`` from the design seat [steps], ``friction`` [-] (1 = the design's), and with
        ``sd`` their standard deviations ``sd_steps``, ``sd_friction`` (first-order propagation;
        the fits are independent, BC and CC are taken uncorrelated).
    """
    b = breaker
    tb = BO * BC * b.J1 - b.kO * b.xO1 * b.rO      # P − f·TOf [N·m]
    tc = CC * BC * b.J1 - b.kO * b.xO0 * b.rO      # P + f·TCf [N·m]
    s = b.TOf + b.TCf
    P = (b.TCf * tb + b.TOf * tc) / s
    out = {"steps": P / step_nm(b), "friction": (tc - tb) / s}
    if sd is not None:
        # d(P, f)/d(BO, BC, CC)
        dP = (b.TCf * BC * b.J1 / s, (b.TCf * BO + b.TOf * CC) * b.J1 / s, b.TOf * BC * b.J1 / s)
        df = (-BC * b.J1 / s, (CC - BO) * b.J1 / s, BC * b.J1 / s)
        v = (sd["BO"] ** 2, sd["BC"] ** 2, sd["CC"] ** 2)
        out["sd_steps"] = math.sqrt(sum(d * d * x for d, x in zip(dP, v))) / step_nm(b)
        out["sd_friction"] = math.sqrt(sum(d * d * x for d, x in zip(df, v)))
    return out


def setting(reading: dict, breaker: Breaker, *, reference: dict | None = None,
            kO_tolerance: float = 0.03) -> dict:
    """A pair's setting with its 95 % interval [steps].

    With ``reference`` (the commissioning pair's :func:`pair_reading` and its known ``steps``),
    the pair is read relative to it: κ's offset cancels and the interval holds both readings'
    errors. Without one, the setting is from the design seat and the interval also holds the
    unit's unknown κ, uniform within ±``kO_tolerance`` (sd tolerance/√3 × :func:`steps_per_kO`).
    """
    if reference is not None:
        steps = reference["known_steps"] + reading["steps"] - reference["steps"]
        sd = math.hypot(reading["sd_steps"], reference["sd_steps"])
        basis = "relative to the unit's commissioning pair"
        kappa_sd = 0.0
    else:
        steps = reading["steps"]
        kappa_sd = kO_tolerance / math.sqrt(3.0) * steps_per_kO(breaker)
        sd = math.hypot(reading["sd_steps"], kappa_sd)
        basis = (f"counted from the design seat. This unit's own spring stiffness is not known, so the "
                 f"interval allows for the spring maker's ±{100 * kO_tolerance:g} % tolerance; record a "
                 "commissioning pair (below) to narrow it")
    return {"steps": steps, "sd_steps": sd, "ci95": (steps - Z95 * sd, steps + Z95 * sd),
            "nearest": round(steps), "friction": reading["friction"], "sd_friction": reading.get("sd_friction"),
            "kO_sd_steps": kappa_sd, "basis": basis}

