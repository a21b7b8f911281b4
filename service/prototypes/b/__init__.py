"""Prototype B: an independently written virtual prototype of the reference 252 kV
spring-operated breaker mechanism, used as foreign test data for gap diagnosis.

It follows the physics of the paper (springs from Table 1 geometry, inertias, puffer and buffer
dampers) in its own equations of motion (torques on the shafts, a two-body pull rod, Radau with
events; see ``opening_dynamics`` and ``closing_dynamics``), and adds named effects, each
switched on with a strength (0 = the reduced model's form, 1 = realistic in service).

Interface
---------
EFFECTS : tuple
    The ten catalogue effects: orifice_buffer, puffer_gas, linkage_kinematics, rod_elasticity,
    stribeck_friction, viscous_friction, spring_nonlinearity, sensor_nonlinearity,
    contact_wipe, cam_friction.
OUTSIDE : tuple
    Effects outside the catalogue: sensor_lag (first-order transducer lag), latch_ramp
    (latch releasing the driving torque over a ramp).
OPERATIONS : dict
    effect -> ("open",), ("close",) or ("open", "close").
REALISTIC : dict
    effect -> what strength 1.0 means and what it does to the curve.
simulate_capture(operation, effect=None, strength=0.0, *, rng, spread=0.06, noise_rad=1.5e-3,
                 sample_rate_hz=128000) -> (Capture, truth)
    One capture (drivers.capture.Capture: travel in rad from closed, vibration in g with the
    latch shock; ~20 ms rest before the motion, ~30 ms after the end of the stroke). truth:
    operation, effect (None for controls), strength, outside_catalogue, shape (the effect's
    strength-1 shape parameters), constants (the drawn physical constants), t_shock_s,
    t_motion_s, t_end_of_stroke_s, events_s (times from the first sample).
write_dataset(out_dir, *, seed, per_effect=10, controls=40, strength_range=(0.5, 1.5),
              outside=3) -> list[dict]
    128 kHz 16-bit COMTRADE captures plus manifest.json (a list: stem, operation, effect or
    null, strength, outside_catalogue, truth). per_effect captures per effect and operation
    it acts on, ``controls`` with no effect (half openings, half closings), ``outside`` per
    outside effect; strengths uniform in strength_range; deterministic for a seed.

Each capture draws kO, kC, TOf, TCf, cb, kb uniformly within ±spread of nominal. All modules
are pure physics except ``dataset`` (the breaker file and the COMTRADE output).
"""

from .capture import simulate_capture
from .dataset import write_dataset
from .effects import EFFECTS, OPERATIONS, OUTSIDE, REALISTIC

__all__ = ["EFFECTS", "OUTSIDE", "OPERATIONS", "REALISTIC", "simulate_capture", "write_dataset"]
