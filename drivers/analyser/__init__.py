"""Breaker-analyser exports (timing/DCRM tests): declarative profiles, one generic parser."""

from .parser import AnalyserRecord, Channel, looks_like_analyser, parse_analyser  # noqa: F401
from .profile import COIL, DCRM_CURRENT, KIND_UNITS, RESISTANCE, TRAVEL, Column, HeaderValue, Profile  # noqa: F401
from .profiles import PROFILES  # noqa: F401
