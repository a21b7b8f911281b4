"""The prototype as a drop-in simulator for ``synthesize_capture(simulate=...)``."""

from __future__ import annotations

from collections.abc import Callable

from service.mechanics.breaker import Breaker
from service.mechanics.trajectory import Trajectory
from .effects import Effects, check_operation
from .simulate import simulate_prototype_closing, simulate_prototype_opening


def make_prototype_simulator(breaker: Breaker, effects: Effects, operation: str, *,
                             method: str = "exact") -> Callable[..., Trajectory]:
    """A callable ``(params, t) -> Trajectory`` of the prototype for one operation.

    Parameters
    ----------
    breaker : Breaker
    effects : Effects
    operation : {"open", "close"}
    method : {"exact", "fast"}
        ``exact`` (scipy, the reference) or ``fast`` (compiled RK4).
    """
    check_operation(effects, operation)
    if operation == "open":
        def simulate(params, t):
            return simulate_prototype_opening(params, t, breaker=breaker, effects=effects, method=method)
    else:
        def simulate(params, t):
            return simulate_prototype_closing(params, t, breaker=breaker, effects=effects, method=method)
    simulate.effects = effects
    simulate.operation = operation
    return simulate
