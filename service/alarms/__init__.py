"""Drift alarms on fitted mechanism parameters (DO: buffer oil leak, BO: opening spring).

Pure: the service persists ``DriftState.to_dict()`` per (breaker, parameter) and stores the
``AlarmEvent``s that ``update``, ``acknowledge`` and ``reset_baseline`` return.
"""

from service.alarms.actions import (acknowledge, health_status, observations_from_fit, replay,
                                    reset_baseline)
from service.alarms.baseline import Model, fit_model
from service.alarms.drift import normal_score, t_for_score, update
from service.alarms.observation import AlarmEvent, FitObservation, check_temperature
from service.alarms.state import Baseline, DriftState
from service.alarms.settings import DEFAULT_WATCHED, DIRECTIONS, DriftSettings

__all__ = [
    "AlarmEvent", "Baseline", "DriftSettings", "DriftState", "FitObservation", "Model",
    "DEFAULT_WATCHED", "DIRECTIONS", "acknowledge", "check_temperature", "fit_model",
    "health_status", "normal_score", "observations_from_fit", "replay", "reset_baseline",
    "t_for_score", "update",
]
