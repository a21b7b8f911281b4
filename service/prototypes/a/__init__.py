"""The virtual prototype: the reduced models plus optional physical effects (issue 6).

    from service.prototypes.a import Effects, make_prototype_simulator
    sim = make_prototype_simulator(breaker, Effects(orifice_buffer=0.6), "open")
    synthesize_capture(breaker, "open", params, rng=rng, simulate=sim)

See docs/diagnosis.md for the catalogue and its equations.
"""

from .effects import EFFECT_NAMES, OPERATIONS, REALISTIC, REGIONS, UPPER, Effects, check_operation
from .factory import make_prototype_simulator
from .effects import FAMILY, LOCALITY, SHAPES, SIGNED, effect_vector, shape_bounds, shape_defaults
from .simulate import prototype_state, simulate_prototype_closing, simulate_prototype_opening

__all__ = [
    "EFFECT_NAMES", "OPERATIONS", "REALISTIC", "REGIONS", "UPPER", "Effects", "check_operation",
    "make_prototype_simulator", "prototype_state", "simulate_prototype_closing", "simulate_prototype_opening",
    "FAMILY", "LOCALITY", "SHAPES", "SIGNED", "effect_vector", "shape_bounds", "shape_defaults",
]
