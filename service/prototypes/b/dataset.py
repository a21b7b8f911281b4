"""The one I/O module of prototype B: the reference breaker, and writing a labelled dataset."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from service.acquisition.comtrade_writer import write_comtrade

from .capture import simulate_capture
from .effects import EFFECTS, OPERATIONS, OUTSIDE
from .reference import REFERENCE_BREAKER, reference_mechanism  # noqa: F401 (re-exported)


def dataset_plan(*, seed: int, per_effect: int = 10, controls: int = 40,
                 strength_range=(0.5, 1.5), outside: int = 3) -> list[tuple]:
    """(operation, effect, strength) per capture, in a seeded shuffled order."""
    rng = np.random.default_rng([seed, 0])
    lo, hi = strength_range
    plan = [("open" if i % 2 == 0 else "close", None, 0.0) for i in range(controls)]
    for effect in EFFECTS:
        for op in OPERATIONS[effect]:
            plan += [(op, effect, float(rng.uniform(lo, hi))) for _ in range(per_effect)]
    for effect in OUTSIDE:
        ops = OPERATIONS[effect]
        plan += [(ops[i % len(ops)], effect, float(rng.uniform(lo, hi))) for i in range(outside)]
    order = rng.permutation(len(plan))
    return [plan[i] for i in order]


def write_dataset(out_dir, *, seed: int, per_effect: int = 10, controls: int = 40,
                  strength_range=(0.5, 1.5), outside: int = 3) -> list[dict]:
    """Write 128 kHz 16-bit COMTRADE captures and ``manifest.json`` into ``out_dir``.

    Returns the manifest: one entry per capture with ``stem``, ``operation``, ``effect`` (None
    for controls), ``strength``, ``outside_catalogue`` and ``truth``. File stems do not reveal
    the effect. Deterministic for a given seed.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plan = dataset_plan(seed=seed, per_effect=per_effect, controls=controls,
                        strength_range=strength_range, outside=outside)
    seeds = np.random.SeedSequence([seed, 1]).spawn(len(plan))
    mech = reference_mechanism()
    manifest = []
    for i, ((op, effect, strength), ss) in enumerate(zip(plan, seeds)):
        stem = f"pb{i:04d}"
        cap, truth = simulate_capture(op, effect, strength, rng=np.random.default_rng(ss), mechanism=mech)
        write_comtrade(cap, out, stem, format="BINARY")
        manifest.append({"stem": stem, "operation": op, "effect": effect, "strength": strength,
                         "outside_catalogue": effect in OUTSIDE, "truth": truth})
    tmp = out / ".manifest.json.tmp"
    tmp.write_text(json.dumps(manifest, indent=1) + "\n")
    os.replace(tmp, out / "manifest.json")
    return manifest
