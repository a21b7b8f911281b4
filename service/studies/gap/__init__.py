"""``hvcb study gap``: the study of the breaker-level gap diagnosis (issue 29).

runner (write groups, diagnose blind, oracle) → oracle (detectable: Δχ² ≥ 100 of the exact
curves over the reduced fit) → scoring (the Acceptance's rules) → calibration (isotonic,
leave-one-prototype-out) → report (JSON, Markdown). docs/gap-study.md states the protocol.
"""

from .runner import rescore, run_gap_study

__all__ = ["run_gap_study", "rescore"]
