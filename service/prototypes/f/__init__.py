"""Prototype F (blind, from Yan et al. 2026): opening of the reference 252 kV breaker. Test instrument only."""
from .groups import write_groups  # noqa: F401
