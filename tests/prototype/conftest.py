from pathlib import Path

import numpy as np
import pytest

from service.breaker_file import load_breaker

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def breaker():
    return load_breaker(ROOT / "config/breakers/reference-252kV.toml")


@pytest.fixture(scope="session")
def params(breaker):
    return breaker.design_parameters()


@pytest.fixture(scope="session")
def t_grid():
    return np.arange(0.0, 0.1, 1 / 32000)
