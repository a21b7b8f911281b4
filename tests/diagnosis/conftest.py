from pathlib import Path

import numpy as np
import pytest

from service.acquisition.synthetic import synthesize_capture
from service.breaker_file import load_breaker
from service.prototypes.a import Effects, make_prototype_simulator

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def breaker():
    return load_breaker(ROOT / "config/breakers/reference-252kV.toml")


def _make_capture(breaker, op, effects=Effects(), seed=101, **kw):
    sim = make_prototype_simulator(breaker, effects, op, method="fast")
    cap, _ = synthesize_capture(breaker, op, breaker.design_parameters(), rng=np.random.default_rng(seed),
                                simulate=sim, **kw)
    return cap


@pytest.fixture(scope="session")
def make_capture():
    return _make_capture

