"""Prototype D: a blind virtual prototype of a spring-operated HV circuit-breaker mechanism.

A test instrument (production code never imports it), written from the physics and the
effects' names without the other prototypes or the diagnosis (docs/prototype-d.md).
``write_groups`` writes a study set of captures with their truths; ``EFFECTS`` are the
catalogue effects it implements, ``OUTSIDE`` the effects outside the catalogue, ``OPERATIONS``
the operations each acts on.
"""

from service.prototypes.d.effects import EFFECTS, OPERATIONS, OUTSIDE
from service.prototypes.d.groups import write_groups

__all__ = ["EFFECTS", "OPERATIONS", "OUTSIDE", "write_groups"]
