"""Prototype E: a blind virtual prototype of the reference 252 kV spring-operated breaker.

Mechanism family: output shaft -> crank-slider four-bar -> pull rod -> moving contact, an
oil dashpot buffer (orifice law as an effect), a puffer with compressible SF6, a travel
transducer read through a slotted lever.  See docs/prototype-e.md.
"""
from .study import EFFECTS, OUTSIDE, OPERATIONS, write_groups

__all__ = ["EFFECTS", "OUTSIDE", "OPERATIONS", "write_groups"]
