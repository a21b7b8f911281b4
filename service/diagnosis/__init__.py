"""Sim-to-real gap diagnosis (issue 6): where the reduced model misses, which catalogued
physical effect explains it, and how far the gap shrinks once it is added."""

from .diagnose import DiagnosisError, diagnose

__all__ = ["DiagnosisError", "diagnose"]
