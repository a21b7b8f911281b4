"""Drift alarms on fitted mechanism parameters (DO: buffer oil leak, BO: opening spring).

Pure: the service persists ``DriftState.to_dict()`` per (breaker, parameter) and stores the
``AlarmEvent``s that ``update``, ``acknowledge`` and ``reset_baseline`` return.
"""

from service.alarms.drift import (
    AlarmEvent,
    Baseline,
    DriftState,
    FitObservation,
    acknowledge,
    fit_baseline,
    health_status,
    normal_score,
    observations_from_fit,
    replay,
    reset_baseline,
    standardised_deviation,
    update,
)
from service.alarms.settings import DEFAULT_WATCHED, DIRECTIONS, DriftSettings

__all__ = [
    "AlarmEvent", "Baseline", "DriftSettings", "DriftState", "FitObservation", "DEFAULT_WATCHED",
    "DIRECTIONS", "acknowledge", "fit_baseline", "health_status", "normal_score",
    "observations_from_fit", "replay", "reset_baseline", "standardised_deviation", "update",
]
