"""Model-parameter estimation from travel curves (paper Section 3).

The names below are imported on first use (PEP 562): importing one piece of the package
(``hvcb fit --help`` reads ``commands``) does not load CMA-ES, scipy and numba. The workers
import ``service.estimation.fit`` at start to compile before the first fit."""

_NAMES = {"FitSettings": ".fit", "fit_capture": ".fit", "FitResult": ".result", "FitError": ".window"}

__all__ = ["FitError", "FitResult", "FitSettings", "fit_capture"]


def __getattr__(name: str):
    if name in _NAMES:
        import importlib

        value = getattr(importlib.import_module(_NAMES[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
