"""The catalogue of physical effects the reduced models leave out (issue 29): names, where each
acts, the family laws with their physical bounds (one module per effect), and the compiled
integrator of the reduced models plus any set of them. Prototypes and the diagnosis both use it;
the strengths typical of a breaker live in its breaker file."""

from .catalogue import (EFFECT_NAMES, FAMILY, LOCALITY, N_SHAPES, NAMES_IN_WORDS, OPERATIONS, PHYSICAL_UPPER,
                        REFERENCE_STRENGTHS, REGIONS, SHAPES, SIGNED, effect_vector, in_words, shape_bounds,
                        shape_defaults)
from .integrator import closing_constants, integrate, opening_constants, simulate_effects

__all__ = ["EFFECT_NAMES", "FAMILY", "LOCALITY", "N_SHAPES", "NAMES_IN_WORDS", "OPERATIONS", "PHYSICAL_UPPER",
           "REFERENCE_STRENGTHS", "REGIONS", "SHAPES", "SIGNED", "effect_vector", "in_words", "shape_bounds",
           "shape_defaults", "closing_constants", "integrate", "opening_constants", "simulate_effects"]
