"""Helpers of the browser tests and the UI benchmark: the app served on loopback, a history of
synthetic captures, sign-in, canvas ink, screenshots."""

from __future__ import annotations

import os
import re
import shutil
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pytest

from tests.live_server import LiveServer

REPO = Path(__file__).resolve().parents[2]
BREAKER_FILE = REPO / "config" / "breakers" / "reference-252kV.toml"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
T0 = datetime(2026, 11, 2, 6, 0, tzinfo=timezone.utc)


def chromium_path() -> str | None:
    path = os.environ.get("HVCB_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    return path if path and Path(path).exists() else None


class LiveApp:
    """The app served over HTTP on loopback, with a key per role."""

    def __init__(self, app, base: str, keys: dict):
        self.app, self.base, self.keys = app, base, keys

    @property
    def Session(self):
        return self.app.state.Session

    def ingest(self, capture, kind: str) -> int:
        result = self.app.state.monitor.ingest(capture, breaker_id=1, operation=kind, source="upload")
        return result.operation_id

    def wait_fits(self, timeout: float = 120.0) -> None:
        from service.storage import crud

        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.Session() as s:
                if crud.queue_depth(s) == 0:
                    return
            time.sleep(0.1)
        raise AssertionError(f"fits still pending after {timeout} s")


def synth(breaker, kind: str, seed: int, scale: dict | None = None, start_time=None):
    from drivers.synthetic import synthesize_capture

    p = dict(breaker.design_parameters())
    rng = np.random.default_rng(seed)
    for k in p:
        p[k] *= 1.0 + rng.normal(0.0, 0.003)
    for k, v in (scale or {}).items():
        p[k] *= v
    cap, _ = synthesize_capture(breaker, kind, p, rng=rng)
    return type(cap)(**{**cap.__dict__, "start_time": start_time})


def history(breaker, n_open: int = 12, leak_from: int = 6, close_every: int = 4):
    """A short history: healthy openings, then DO falling 6 % per opening (a buffer oil leak)."""
    out = []
    for i in range(n_open):
        scale = {"DO": 0.94 ** (i - leak_from + 1)} if i >= leak_from else None
        out.append(("open", synth(breaker, "open", 100 + i, scale, T0 + timedelta(minutes=10 * i))))
        if (i + 1) % close_every == 0:
            out.append(("close", synth(breaker, "close", 200 + i, None, T0 + timedelta(minutes=10 * i + 5))))
    return out


def start_server(tmp_path, *, name: str | None = None, alarms: dict | None = None, poll_s: float = 1.0):
    """(LiveApp, stop) with the service on a fresh SQLite database and the inline fit executor."""
    from service.api.app import create_app
    from service.settings import load_settings
    from service.storage import crud
    from service.storage.db import upgrade

    data = tmp_path / "data"
    data.mkdir(exist_ok=True)  # an existing one: the service restarts on it
    url = f"sqlite:///{data / 'hvcb.sqlite3'}"
    upgrade(url)
    settings = load_settings(data_dir=data, database_url=url, broker_url="", executor="inline",
                             bootstrap_admin_key=None, alarms=alarms or {"baseline_n": 5},
                             web={"poll_s": poll_s})
    shown = []
    app = create_app(settings, on_key=shown.append)
    server = LiveServer(app, name="hvcb-web-test-server", log_level="warning").start()
    keys = {"admin": shown[0]} if shown else {}
    with app.state.Session() as s, s.begin():
        for role in ("reader", "operator", "admin")[: 2 if shown else 3]:
            keys[role] = crud.create_api_key(s, name=name or f"web-{role}", role=role)[1]

    return LiveApp(app, server.url, keys), server.stop


class PageLog:
    """Console errors, page errors and every request URL of a browser context."""

    def __init__(self, context, base: str):
        self.base = base
        self.errors: list[str] = []
        self.requests: list[str] = []
        context.on("request", lambda r: self.requests.append(r.url))
        context.on("console", lambda m: self.errors.append(f"console: {m.text}") if m.type == "error" else None)

    def watch(self, page):
        page.on("pageerror", lambda e: self.errors.append(f"page error: {e}"))
        return page

    def foreign(self) -> list[str]:
        return [u for u in self.requests if not (u.startswith(self.base + "/") or u == self.base)]


def sign_in(context, live: LiveApp, role: str, log: PageLog | None = None):
    page = context.new_page()
    if log is not None:
        log.watch(page)
    page.goto(live.base + "/")
    assert "/signin" in page.url  # no session: the page asks to sign in
    page.fill("#api-key", live.keys[role])
    page.click("#signin-submit")
    page.wait_for_url(live.base + "/")
    return page


def csrf_of(page) -> str:
    return page.eval_on_selector('form[action="/signout"] input[name="csrf_token"]', "e => e.value")


def canvas_ink(page, selector: str) -> int:
    """Non-transparent pixels drawn on the canvas inside ``selector`` (0 when there is none)."""
    return page.evaluate("""sel => {
        const c = document.querySelector(sel + ' canvas');
        if (!c) return 0;
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let n = 0;
        for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++;
        return n;
    }""", selector)


TEST_MARKUP = ("<img", "onerror", "<script")  # the security tests' strings: never in the docs' pictures


def screenshot(page, name: str) -> None:
    target = os.environ.get("HVCB_WEB_SCREENSHOTS")
    if target:
        text = page.locator("body").inner_text()
        assert not any(m in text for m in TEST_MARKUP), f"the {name} screenshot would show a test string"
        from PIL import Image

        Path(target).mkdir(parents=True, exist_ok=True)
        path = Path(target) / f"{name}.png"
        page.screenshot(path=str(path), full_page=True, animations="disabled")
        with Image.open(path) as im:  # 256-colour palette: a third of the size, same look
            small = im.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT)
        small.save(path, optimize=True)


def slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower())
