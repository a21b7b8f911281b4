"""The spring setting from a breaker's close–open pair (issue 32): physics and the estimator.

The opening spring's nut adds the pre-load P = kO·Δx·rO [N·m]; one grease and temperature state
scales both resistance torques by one friction factor f. The reduced model's parameters carry them
as (Eq. 8 and Eq. 12)

    BO = (kO·xO1·rO + P − f·TOf)/J2        (opening)
    CC = (f·TCf + kO·xO0·rO + P)/J2        (closing)

so one opening sees only P − f·TOf: a nut step (36 N·m) and TOf ±10 % (±60 N·m) are the same
observation, and no rule on an opening alone can beat the 48.5 % of the simulator's true BO. The
closing sees P + f·TCf, with the friction's sign reversed: the pair's 2 × 2 Jacobian is regular.

:func:`identifiability` gives that table (Jacobian and Fisher information per observation set).
:class:`PairSetting` is the proposed classifier on the fitted (AO, BO, BC, CC) of each pair
(:func:`pair_inputs`).
"""

from __future__ import annotations

import numpy as np

from ..mechanics.breaker import Breaker
from ..mechanics.spring_setting import steps_per_kO
from .condition_data import STEP_M

# The fitted parameters the pair estimator reads: the opening's AO and BO, the closing's BC and CC.
PAIR_PARAMETERS = ("AO", "BO", "BC", "CC")


def pair_inputs(AO, BO, BC, CC) -> np.ndarray:
    """The estimator's inputs (n, 4): BC, and AO, BO, CC times BC.

    BC = J2/J1 and J1 is the closing side's (not the opening spring's): AO·BC, BO·BC and CC·BC
    are the torques AO·J2, BO·J2, CC·J2 over J1, free of the unit's J2, which a second unit
    carries within ±3 % (it moved the estimate by half a step across units). BC itself stays an
    input so that Σ holds the closing fit's BC–CC trade-off. CC·BC comes last (:meth:`PairSetting.friction`).
    """
    BC = np.asarray(BC, float)
    return np.column_stack([BC, np.asarray(AO, float) * BC, np.asarray(BO, float) * BC,
                            np.asarray(CC, float) * BC])


def friction_direction(breaker: Breaker) -> tuple:
    """dCC/df [s^-2 per unit friction factor] and one nut step's dCC [s^-2] of the design."""
    jac = jacobian(breaker)
    return jac["CC"]["f"], jac["CC"]["P"] * breaker.kO * breaker.rO * STEP_M


def jacobian(breaker: Breaker) -> dict:
    """d(BO, CC)/d(P, f) of the design: BO [s^-2 per N·m, s^-2 per unit f] and CC likewise."""
    return {"BO": {"P": 1.0 / breaker.J2, "f": -breaker.TOf / breaker.J2},
            "CC": {"P": 1.0 / breaker.J2, "f": breaker.TCf / breaker.J2}}


def identifiability(breaker: Breaker, sd: dict, step_nm: float, f_scale: float = 0.10) -> dict:
    """Which observation carries the setting P and the friction f, and how well.

    Parameters
    ----------
    breaker : Breaker
        The design.
    sd : dict
        Standard deviation of each observation's estimate, ``{"BO": s^-2, "CC": s^-2}`` (the
        fit's scatter within one setting and friction state).
    step_nm : float
        One nut step of pre-load [N·m].
    f_scale : float
        The friction factor's unit for the condition number [-] (the field set's ±10 %), so
        that it compares P in nut steps with f in its own spread.

    Returns
    -------
    dict
        ``jacobian``; per observation set (``opening``, ``closing``, ``pair``): ``rank`` of the
        Fisher information JᵀWJ, its ``condition_number``, and when it is regular ``sd_P_nm``,
        ``sd_P_steps``, ``sd_f`` and ``corr_P_f`` (Cramér–Rao bounds); the condition number is
        that of the information in (P / step_nm, f / f_scale); a rank-1 set carries only
        one combination of P and f (``combination``: coefficients of P and f it sees).
    """
    jac = jacobian(breaker)
    out = {"jacobian": jac, "sd": dict(sd), "step_nm": step_nm, "sets": {}}
    for name, obs in (("opening", ("BO",)), ("closing", ("CC",)), ("pair", ("BO", "CC"))):
        J = np.array([[jac[o]["P"], jac[o]["f"]] for o in obs])
        W = np.diag([1.0 / sd[o] ** 2 for o in obs])
        fisher = J.T @ W @ J
        rank = int(np.linalg.matrix_rank(fisher, tol=1e-9 * np.abs(fisher).max()))
        scale = np.diag([step_nm, f_scale])
        s = np.linalg.svd(scale @ fisher @ scale, compute_uv=False)
        row = {"observations": list(obs), "rank": rank, "fisher": fisher.tolist(),
               "condition_number": float(s[0] / s[-1]) if s[-1] > 0 else float("inf")}
        if rank == 2:
            cov = np.linalg.inv(fisher)
            row.update(sd_P_nm=float(np.sqrt(cov[0, 0])), sd_P_steps=float(np.sqrt(cov[0, 0]) / step_nm),
                       sd_f=float(np.sqrt(cov[1, 1])),
                       corr_P_f=float(cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1])))
        else:
            row["combination"] = {"P": float(J[0, 0] * breaker.J2), "f": float(J[0, 1] * breaker.J2)}
        out["sets"][name] = row
    return out


class PairSetting:
    """The setting of a pair by generalised least squares on its fitted parameter vector.

    Model, per pair: v = μ0 + k·s + e, with v the inputs (:func:`pair_inputs`), k the setting (0-based
    nut steps), s its direction and e the within-setting scatter: the friction state (which
    moves BO and CC in opposite senses, the Jacobian above) plus the fits' errors (AO and BO
    trade off in the opening fit). ``fit`` learns μ0 and s by least squares on the labelled
    training pairs and Σ = cov(e) from their residuals; ``infer`` returns
    k̂ = sᵀΣ⁻¹(v − μ0)/(sᵀΣ⁻¹s) with its standard deviation (sᵀΣ⁻¹s)^(-1/2) in steps, and
    ``predict`` the nearest setting. The friction is the part of e that Σ discounts; the
    setting is the part of v it cannot explain.

    With ``friction`` (the design's dCC/df and the design nut step in CC, from
    :func:`friction_direction`), :meth:`friction` reads the friction factor once the setting is
    known: the closing's CC residual over dCC/df, scaled by the fit's own response to a known
    change of CC (the fitted over the design step; the nut and the friction move the same
    parameter). CC carries the friction: TCf/TOf = 2.7 times BO's share.

    A pair with a failed fit (NaN) gets the label -1 (never correct).
    """

    def __init__(self, friction=None):
        self.friction_model = friction

    def fit(self, X, y):
        X, y = np.asarray(X, float), np.asarray(y, int)
        ok = np.all(np.isfinite(X), axis=1)
        X, y = X[ok], y[ok]
        self.classes_ = np.unique(y)
        A = np.column_stack([np.ones(y.size), y.astype(float)])
        coef, *_ = np.linalg.lstsq(A, X, rcond=None)
        self.mu0_, self.s_ = coef[0], coef[1]
        resid = X - A @ coef
        cov = np.atleast_2d(np.cov(resid, rowvar=False, ddof=2))
        # A relative floor of 1e-9 on the diagonal: exact values (the ceiling on the simulator's
        # truth) scatter only along the friction, and their Σ is singular.
        self.cov_ = cov + 1e-9 * np.diag(np.diag(cov))
        w = np.linalg.solve(self.cov_, self.s_)
        self.gain_ = w / float(self.s_ @ w)          # k̂ = gain_ · (v − μ0)
        self.sd_steps_ = float(1.0 / np.sqrt(self.s_ @ w))
        return self

    def infer(self, X):
        """Setting estimate [steps] and its standard deviation [steps] per pair."""
        X = np.asarray(X, float)
        k = (X - self.mu0_) @ self.gain_
        return k, np.full(k.shape, self.sd_steps_)

    def friction(self, X):
        """Friction factor relative to the training pairs' mean [-] (needs ``friction``)."""
        df, step = self.friction_model
        X = np.asarray(X, float)
        k, _ = self.infer(X)
        j = X.shape[1] - 1  # the closing's CC (times BC) is the last input
        resid = X[:, j] - self.mu0_[j] - k * self.s_[j]
        return resid / (df * self.s_[j] / step)

    def predict(self, X):
        k, _ = self.infer(X)
        lo, hi = self.classes_.min(), self.classes_.max()
        labels = np.clip(np.rint(np.nan_to_num(k, nan=-1.0)), lo, hi).astype(int)
        return np.where(np.isfinite(k), labels, -1)


class CommissionedPairSetting(PairSetting):
    """:class:`PairSetting` for a unit it was not trained on, anchored by that unit's
    commissioning pair: one pair ``reference`` (its inputs) recorded at a known setting
    ``known`` [steps]. The unit's spring rate kO moves every estimate by one offset (it enters
    the pre-load torques of BO and CC alike, :func:`~service.mechanics.spring_setting.steps_per_kO`
    per unit of κ); the reference pair measures that offset, and it is removed."""

    def __init__(self, reference, known: float, friction=None):
        super().__init__(friction)
        self.reference, self.known = np.asarray(reference, float), float(known)

    def fit(self, X, y):
        super().fit(X, y)
        k_ref, _ = super().infer(self.reference[None, :])
        self.offset_ = float(k_ref[0]) - self.known
        return self

    def infer(self, X):
        """Setting [steps] and its sd [steps]: the pair's and the reference's errors together."""
        k, sd = super().infer(X)
        return k - self.offset_, np.sqrt(2.0) * sd


def identifiability_kO(breaker: Breaker, cov: np.ndarray, step_nm: float, n_pairs: int,
                       f_scale: float = 0.10) -> dict:
    """The identifiability table with the unit's spring rate free: unknowns (P, f, κ), κ the
    unit's kO over the design's, from the fits' own covariance ``cov`` of (AO, BO, CC) [s^-2].

    Jacobian (the design's, per unit of each unknown): BO (1/J2, −TOf/J2, kO·xO1·rO/J2), CC
    (1/J2, TCf/J2, kO·xO0·rO/J2), AO (0, 0, kO·rO²/J2). P and f are per pair; κ is the unit's,
    shared by its ``n_pairs`` pairs, so its information adds up over them.

    Returns
    -------
    dict
        ``sets``: per observation set its ``rank`` in (P, f, κ), and when κ is not identified
        the direction it cannot see (``steps_per_kO_percent``: nut steps per 1 % of kO); when
        it is, the Cramér–Rao sd of κ from one pair and from ``n_pairs``, and of the setting
        [steps] with κ from the unit's pairs. ``commissioned``: one pair at a known setting
        removes κ's offset; the sd of a reading is √2 × the κ-known pair sd.
    """
    b = breaker
    J = {"AO": [0.0, 0.0, b.kO * b.rO ** 2 / b.J2],
         "BO": [1.0 / b.J2, -b.TOf / b.J2, b.kO * b.xO1 * b.rO / b.J2],
         "CC": [1.0 / b.J2, b.TCf / b.J2, b.kO * b.xO0 * b.rO / b.J2]}
    names = ("AO", "BO", "CC")
    cov = np.asarray(cov, float)
    per_kappa = steps_per_kO(b)
    out = {"unknowns": ["P [N·m]", "f [-]", "kappa = kO/kO_design [-]"], "jacobian": J,
           "steps_per_kO_percent": per_kappa / 100.0, "n_pairs": n_pairs, "sets": {}}
    for name, obs in (("pair BO, CC", ("BO", "CC")), ("pair AO, BO, CC", ("AO", "BO", "CC"))):
        idx = [names.index(o) for o in obs]
        A = np.array([J[o] for o in obs])
        W = np.linalg.inv(cov[np.ix_(idx, idx)])
        fisher = A.T @ W @ A
        scale = np.diag([step_nm, f_scale, 0.01])  # P in steps, f in its ±10 %, κ in 1 %
        sv = np.linalg.svd(scale @ fisher @ scale, compute_uv=False)
        rank = int(np.sum(sv > 1e-9 * sv[0]))
        row = {"observations": list(obs), "rank": rank, "condition_number":
               float(sv[0] / sv[-1]) if sv[-1] > 1e-12 * sv[0] else None}  # None: singular (JSON has no ∞)
        if rank < 3:
            row["unseen"] = f"κ +1 % reads as {per_kappa / 100:+.2f} nut steps: P and κ trade exactly"
        else:
            # Per pair: Schur complement of (P, f) gives κ's information; the unit's pairs add it.
            Ipp, Ipk, Ikk = fisher[:2, :2], fisher[:2, 2], fisher[2, 2]
            info_k = float(Ikk - Ipk @ np.linalg.solve(Ipp, Ipk))
            sd_k1 = 1.0 / np.sqrt(info_k)
            sd_kn = sd_k1 / np.sqrt(n_pairs)
            sd_P_known = float(np.sqrt(np.linalg.inv(Ipp)[0, 0]))
            row.update(sd_kappa_one_pair=sd_k1, sd_kappa_unit=sd_kn,
                       sd_steps_kappa_from_unit=float(np.hypot(sd_P_known / step_nm, per_kappa * sd_kn)))
        out["sets"][name] = row
    Ipp = np.array([J[o][:2] for o in ("BO", "CC")])
    W = np.linalg.inv(cov[np.ix_([1, 2], [1, 2])])
    sd_P = float(np.sqrt(np.linalg.inv(Ipp.T @ W @ Ipp)[0, 0])) / step_nm
    out["commissioned"] = {"sd_steps": float(np.sqrt(2.0) * sd_P), "sd_steps_kappa_known": sd_P,
                           "note": "one pair at a known setting: κ's offset cancels; a reading carries "
                                   "its own and the reference's error"}
    return out
