"""Prognosis: when a breaker's temperature-compensated parameter crosses its maintenance limit.

Pure (no I/O, no wall clock), like service.alarms, whose detector state it reads. See
docs/prognosis.md for the model and its calibration (bench/prognosis.py).
"""

from service.prognosis.forecast import (MODEL, Prognosis, Quantiles, compensated, operation_rate,
                                        prognose)
from service.prognosis.trend import Trend, fit_trend

__all__ = ["MODEL", "Prognosis", "Quantiles", "Trend", "compensated", "fit_trend", "operation_rate",
           "prognose"]
