"""Model-parameter estimation from travel curves (paper Section 3)."""

from .fit import FitSettings, fit_capture
from .result import FitResult
from .window import FitError

__all__ = ["FitError", "FitResult", "FitSettings", "fit_capture"]
