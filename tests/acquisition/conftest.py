"""Fixtures for the acquisition tests: the reference breaker and the detected acceptance stream."""

from __future__ import annotations

from pathlib import Path

import pytest

from drivers.stream_script import acceptance_script
from service.acquisition.trigger import TriggerDetector, TriggerSettings
from service.breaker_file import load_breaker

ROOT = Path(__file__).resolve().parents[2]
BREAKER_FILE = ROOT / "config" / "breakers" / "reference-252kV.toml"
ACCEPTANCE_SEED = 20260321


@pytest.fixture(scope="session")
def breaker():
    return load_breaker(BREAKER_FILE)


@pytest.fixture(scope="session")
def settings(breaker):
    return TriggerSettings.from_breaker(breaker)


def run_detector(stream, settings, block_samples=4096):
    """Feed a scripted stream through a fresh detector; returns (operations, detector)."""
    detector = TriggerDetector(settings, stream.fs)
    found = []
    for block in stream.blocks(block_samples):
        found += detector.feed(block)
    return found + detector.flush(), detector


@pytest.fixture(scope="session")
def acceptance(breaker, settings):
    """The issue's 60 s stream with its truth, and what the detector found in it."""
    stream = acceptance_script(breaker, ACCEPTANCE_SEED)
    found, _ = run_detector(stream, settings)
    return stream, found
