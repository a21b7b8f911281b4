"""Stage 4 — the learnt scorer (issue 48 item 2): the probability of every hypothesis from its
features, replacing the softmax of counts of samples, the Occam term and the naming threshold.

A **conditional logit** (McFadden 1974, "Conditional logit analysis of qualitative choice
behavior", in *Frontiers in Econometrics*, 105–142): a multinomial logistic regression whose
classes are the group's own hypotheses, each described by its features φ(g, h) (``vector``),
with one weight vector w shared by all of them,

    P(h | g) = exp(w·z(g, h)) / Σ_h' exp(w·z(g, h')),   z = (φ − mean)/scale.

Sharing w is what lets 57 hypotheses be learnt from a few hundred groups: a pair no training
group held is scored by the same rules as the pairs that were. Per-effect terms (whether h holds
effect e) let it learn which family stands in for which. The features (``features.collect``) are
relative to ``none`` and to the best hypothesis and normalised by the group's gap above the
noise, so a group of 30,000 rows and one of 1,500 speak the same units.

The fitted model is data: ``scorer.json`` beside this module (weights, standardisation, the
conformal threshold of the answer's set, the Learn-then-Test naming threshold, and where they
came from: corpus, its size, prototypes, sensor kinds, date). Loading checks the feature names;
nothing here needs scikit-learn or scipy.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..mechanics.effects import EFFECT_NAMES

SHIPPED = Path(__file__).with_name("scorer.json")
OUTSIDE = "outside_catalogue"
CLIP = 3.0     # shares of the gap are clipped to ±3 (beyond it the fit took noise, or failed)

BASE = ("is_none", "is_single", "is_pair", "is_outside",
        "elpd_over_gap", "elpd_minus_best_over_gap", "elpd_log", "is_best",
        "shrink_mean", "shrink_min", "shrink_sd", "shrink_all", "units_agree",
        "where", "where_sd", "where_from_gap", "dim",
        "none_x_gap", "none_x_white", "outside_x_gap", "outside_x_white", "outside_x_units",
        "pair_x_gap")
FEATURES = BASE + tuple(f"has_{e}" for e in EFFECT_NAMES)


class ScorerError(ValueError):
    """The shipped scorer is missing or does not match these features."""


def gap_scale(group: dict) -> float:
    """The group's gap above the noise [nats]: ½(χ² − dof), at least ½√(2·dof) (the noise's sd)."""
    dof = float(group.get("dof", group["rows"]))
    return max(0.5 * (float(group["chi2"]) - dof), 0.5 * np.sqrt(2.0 * max(dof, 1.0)))


def candidates(feats: dict) -> list:
    """The group's hypotheses, in a fixed order: none, then the others by name."""
    return ["none"] + sorted(k for k in feats["hypotheses"] if k != "none")


def vector(feats: dict, name: str) -> np.ndarray:
    """φ(g, h) of hypothesis ``name`` of a group's ``features`` (names ``FEATURES``)."""
    g = feats["group"]
    hyp = feats["hypotheses"]
    G = gap_scale(g)
    best = max(float(h["elpd"]) for h in hyp.values()) if hyp else 0.0
    best = max(best, 0.0)
    is_none = name == "none"
    is_out = name == OUTSIDE
    parts = [] if is_none or is_out else name.split("+")
    h = hyp.get(name, {"elpd": 0.0, "lpd": [], "dim": 0})
    elpd = 0.0 if is_none else float(h["elpd"])
    sh = np.clip(np.asarray(h.get("shrink") or [0.0], float), -CLIP, CLIP)
    lpd = np.asarray(h.get("lpd") or [0.0], float)
    gap_pos = np.log1p(max(float(g["gap_sigma"]), 0.0))
    white = np.log(max(float(g["whiteness"]), 1e-3))
    units = np.log(max(float(g["units"]), 1.0))
    v = {
        "is_none": float(is_none), "is_single": float(len(parts) == 1), "is_pair": float(len(parts) == 2),
        "is_outside": float(is_out),
        "elpd_over_gap": float(np.clip(elpd / G, -CLIP, CLIP)),
        "elpd_minus_best_over_gap": float(np.clip((elpd - best) / G, -10.0, 0.0)),
        "elpd_log": float(np.sign(elpd) * np.log1p(abs(elpd))),
        "is_best": float(abs(elpd - best) <= 1e-9 * max(abs(best), 1.0)),
        "shrink_mean": float(np.mean(sh)) if parts else 0.0,
        "shrink_min": float(np.min(sh)) if parts else 0.0,
        "shrink_sd": float(np.std(sh)) if parts and sh.size > 1 else 0.0,
        "shrink_all": float(np.clip(h.get("shrink_all", 0.0), -CLIP, CLIP)) if parts else 0.0,
        "units_agree": float(np.mean(lpd > 0)) if not is_none else 0.0,
        "where": float(h.get("where", 0.5)) if parts else 0.0,
        "where_sd": float(h.get("where_sd", 0.0)) if parts else 0.0,
        "where_from_gap": float(abs(h.get("where", 0.5) - g.get("where", 0.5))) if parts else 0.0,
        "dim": float(h.get("dim", 0)) / 10.0,
        "none_x_gap": float(is_none) * gap_pos, "none_x_white": float(is_none) * white,
        "outside_x_gap": float(is_out) * gap_pos, "outside_x_white": float(is_out) * white,
        "outside_x_units": float(is_out) * units, "pair_x_gap": float(len(parts) == 2) * gap_pos,
    }
    for e in EFFECT_NAMES:
        v[f"has_{e}"] = float(e in parts)
    return np.array([v[k] for k in FEATURES])


def design(feats: dict):
    """(hypothesis names, their feature matrix) of one group."""
    names = candidates(feats)
    return names, np.vstack([vector(feats, k) for k in names])


def softmax_rows(u: np.ndarray) -> np.ndarray:
    u = u - np.max(u)
    p = np.exp(u)
    return p / p.sum()


class Scorer:
    """The fitted conditional logit: ``coef_`` over ``FEATURES`` after standardising by
    ``mean_``/``scale_``; ``predict_proba(features) -> {hypothesis: probability}``."""

    def __init__(self, coef, mean, scale, meta=None):
        self.coef_ = np.asarray(coef, float)
        self.mean_ = np.asarray(mean, float)
        self.scale_ = np.asarray(scale, float)
        self.meta = dict(meta or {})

    @property
    def qhat(self) -> float:
        """The conformal threshold of the answer's set (1: the whole catalogue)."""
        return float((self.meta.get("set") or {}).get("qhat", 1.0))

    @property
    def alpha(self) -> float:
        return float((self.meta.get("set") or {}).get("alpha", 0.1))

    @property
    def lam(self):
        """Learn then Test's naming threshold, or None (nothing is named)."""
        v = (self.meta.get("name") or {}).get("lambda")
        return None if v is None else float(v)

    def utilities(self, X: np.ndarray) -> np.ndarray:
        return ((X - self.mean_) / self.scale_) @ self.coef_

    def predict_proba(self, feats: dict) -> dict:
        names, X = design(feats)
        p = softmax_rows(self.utilities(X))
        return {k: float(v) for k, v in zip(names, p)}

    def to_dict(self) -> dict:
        return {"features": list(FEATURES), "coef": self.coef_.tolist(), "mean": self.mean_.tolist(),
                "scale": self.scale_.tolist(), **self.meta}

    @classmethod
    def from_dict(cls, d: dict, source: str = "scorer") -> "Scorer":
        if list(d.get("features", [])) != list(FEATURES):
            raise ScorerError(f"{source}: its features ({len(d.get('features', []))}) are not this "
                              f"version's ({len(FEATURES)}): retrain it (bench/gap_scorer.py)")
        meta = {k: v for k, v in d.items() if k not in ("features", "coef", "mean", "scale")}
        return cls(d["coef"], d["mean"], d["scale"], meta)


@lru_cache(maxsize=1)
def shipped() -> Scorer:
    """The scorer shipped beside this module (``scorer.json``)."""
    if not SHIPPED.exists():
        raise ScorerError(f"{SHIPPED}: no trained scorer is shipped (bench/gap_scorer.py writes it)")
    try:
        d = json.loads(SHIPPED.read_text())
    except json.JSONDecodeError as exc:
        raise ScorerError(f"{SHIPPED}: not valid JSON ({exc})") from None
    return Scorer.from_dict(d, str(SHIPPED))
