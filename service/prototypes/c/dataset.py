"""Prototype C's data set: groups of captures (one unit each) as COMTRADE + manifest.json.

This is the prototype's only I/O. Stems (pc_g012_c3) do not reveal the effect; the truth is in
the manifest only.
"""

from __future__ import annotations

import copy
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from service.acquisition.comtrade_writer import write_comtrade
from service.prototypes.a.groups import write_clean

from .capture import draw_conditions, simulate_capture
from .effects import EFFECTS, OPERATIONS, OUTSIDE, check_effects, draw_shapes
from .mechanism import Unit, draw_constants

STRENGTH_RANGE = (0.7, 1.2)


def _plan(rng: np.random.Generator, per_effect: int, controls: int, two_effect: int, outside: int) -> list:
    """[(operation, effects)] for every group, in a fixed order."""
    plan = []
    for name in EFFECTS:
        for op in OPERATIONS[name]:
            plan += [(op, {name: None}) for _ in range(per_effect)]
    for op in ("open", "close"):
        plan += [(op, {}) for _ in range(controls)]
    for _ in range(two_effect):
        op = ("open", "close")[int(rng.integers(2))]
        names = [n for n in EFFECTS if op in OPERATIONS[n]]
        a, b = rng.choice(len(names), size=2, replace=False)
        plan.append((op, {names[int(a)]: None, names[int(b)]: None}))
    for name in OUTSIDE:                 # ``outside`` groups per outside effect, operations alternating
        ops = OPERATIONS[name]
        plan += [(ops[i % len(ops)], {name: None}) for i in range(outside)]
    return plan


def write_groups(out_dir, *, seed: int, per_effect: int = 4, controls: int = 6, two_effect: int = 4,
                 outside: int = 2, captures_per_group: int = 5) -> list:
    """Write the groups' captures (128 kHz BINARY COMTRADE) and manifest.json into ``out_dir``.

    per_effect groups for every (effect, operation) it acts on, ``controls`` healthy groups per
    operation, ``two_effect`` groups with two effects of one operation, ``outside`` groups per
    outside effect (operations alternating). Strengths are uniform in 0.7-1.2; conditions are
    drawn per capture.
    Returns the manifest (list of group dicts). Deterministic for a seed.
    """
    for name, v in (("per_effect", per_effect), ("controls", controls), ("two_effect", two_effect),
                    ("outside", outside), ("captures_per_group", captures_per_group)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {v!r}")
    if captures_per_group < 1:
        raise ValueError("captures_per_group must be at least 1")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    root = np.random.default_rng(seed)
    plan = _plan(root, per_effect, controls, two_effect, outside)
    manifest = []
    for gi, (op, names) in enumerate(plan):
        rng = np.random.default_rng([int(seed), gi])
        effects = check_effects({n: float(rng.uniform(*STRENGTH_RANGE)) for n in names})
        unit = Unit(constants=draw_constants(rng, 0.03), effects=effects, shapes=draw_shapes(rng, effects))
        stems, truths = [], []
        for ci in range(captures_per_group):
            stem = f"pc_g{gi:03d}_c{ci}"
            cond = draw_conditions(rng)
            twin = copy.deepcopy(rng)       # the same draws, for the noiseless travel (write_clean)
            cap, truth = simulate_capture(unit, op, conditions=cond, rng=rng)
            write_comtrade(cap, out, stem, format="BINARY", station="PROTO-C", device=f"unit-{gi:03d}")
            write_clean(out, stem, simulate_capture, unit, op, cond, twin)
            stems.append(stem)
            truths.append(truth)
        manifest.append({"group": f"g{gi:03d}", "operation": op, "effects": effects,
                         "outside_catalogue": any(n in OUTSIDE for n in effects),
                         "stems": stems, "truths": truths})
    _atomic_json(out / "manifest.json", manifest)
    return manifest


def _atomic_json(path: Path, data) -> None:
    fd, tmp = tempfile.mkstemp(prefix=".manifest.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(data, fh, indent=1)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
