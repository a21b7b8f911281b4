"""Browser tests: the real app under uvicorn on loopback, a real headless Chromium (Debian's
package) driven by Playwright. One server and one browser per module.

Without a browser the tests skip with the reason. ``HVCB_CHROMIUM`` names another executable.
``HVCB_WEB_SCREENSHOTS=DIR`` makes the tests save the docs' screenshots there (docs/screenshots).
"""

from __future__ import annotations

import pytest

from .weblive import CHROMIUM_ARGS, chromium_path


@pytest.fixture(scope="module")
def browser():
    exe = chromium_path()
    if exe is None:
        pytest.skip("browser tests off: no Chromium found (apt-get install -y chromium, or set HVCB_CHROMIUM)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("browser tests off: the playwright package is not installed (pip install -e .[dev])")
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS, headless=True)
        try:
            yield b
        finally:
            b.close()


