"""Command-line argument types shared by several ``hvcb`` subcommands."""

from __future__ import annotations

import argparse


def rate_hz(text: str) -> float:
    """``--rate``: samples per second, ``10000``, ``10k`` or ``10kS/s``."""
    t = text.strip().lower().removesuffix("s/s").removesuffix("hz").strip()
    factor = 1e3 if t.endswith("k") else 1.0
    try:
        value = float(t.removesuffix("k")) * factor
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a rate (give samples per second: 10000 or 10k)") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"the rate must be positive, got '{text}'")
    return value
