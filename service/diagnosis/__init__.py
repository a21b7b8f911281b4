"""Sim-to-real gap diagnosis (issue 6): where the reduced model misses, which catalogued
physical effect explains it, and how far the gap shrinks once it is added.

``diagnose`` and ``DiagnosisError`` are imported on first use (PEP 562), so that importing a
piece of the package (``hvcb diagnose --help`` reads ``commands``) does not load the fitting
stack."""

import sys
import types

__all__ = ["DiagnosisError", "diagnose"]


def __getattr__(name: str):
    if name in __all__:
        from .diagnose import DiagnosisError, diagnose

        globals().update(DiagnosisError=DiagnosisError, diagnose=diagnose)
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class _Package(types.ModuleType):
    """The package's name ``diagnose`` is the function, as when it was imported eagerly: the import
    of the submodule ``diagnose`` (which Python binds on its parent) does not replace it."""

    def __setattr__(self, name, value):
        if name == "diagnose" and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
