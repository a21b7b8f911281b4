"""Stage 5 — the answer as a set (issue 48 item 3).

From the scorer's probabilities (``scorer``) and the two thresholds shipped with it:

* the **90 % set**: adaptive prediction sets (APS; Romano, Sesia & Candès 2020, NeurIPS 33),
  their randomisation fixed at U = 0: every hypothesis whose probability mass ranked above it is
  at most q̂, the ⌈(n + 1)·0.9⌉-th smallest such score of the calibration groups' truths
  (``studies.gap.train``). On
  groups exchangeable with the calibration groups it holds the truth with probability ≥ 90 %;
  the calibration groups are simulated (prototypes and sensor kinds named in the scorer's
  provenance), so on a real breaker that is an assumption, which the held-out figures test;
* the **name**: the answer is stated as a set of one only when its probability reaches λ, the
  threshold Learn then Test certified (wrong names ≤ 5 % with 90 % confidence on the
  calibration groups); when no λ passed, nothing is named and the answer is the set.

``status``: ``named`` / ``none`` / ``unexplained`` for a stated set of one, else ``ambiguous``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .scorer import OUTSIDE

UNEXPLAINED = "unexplained"


@dataclass
class AnswerSet:
    """The answer: the most probable hypothesis, its probability, the set (hypothesis names,
    ``outside_catalogue`` for an answer outside the catalogue), its level and whether a name is
    stated (``status``)."""

    top: str
    probability: float
    members: list
    level: float
    status: str
    named: bool
    probabilities: dict = field(default_factory=dict)
    qhat: float = 1.0
    lam: float | None = None

    @property
    def labels(self) -> list:
        """The set as the API states it: ``unexplained`` for ``outside_catalogue``."""
        return [UNEXPLAINED if k == OUTSIDE else k for k in self.members]


def answer_set(probs: dict, qhat: float, lam: float | None, alpha: float = 0.1) -> AnswerSet:
    """The set and the name from ``probs`` (hypothesis → probability) and the thresholds."""
    ranked = sorted(probs.items(), key=lambda kv: (-kv[1], kv[0]))
    members, mass = [], 0.0
    for k, p in ranked:
        if mass > qhat + 1e-12:
            break
        members.append(k)
        mass += p
    top, p_top = ranked[0]
    named = lam is not None and p_top >= lam
    status = ({"none": "none", OUTSIDE: "unexplained"}.get(top, "named") if named else "ambiguous")
    if named:
        members = [top]
    return AnswerSet(top, float(p_top), members, 1.0 - alpha, status, named, dict(ranked), float(qhat), lam)
