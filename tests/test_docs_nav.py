"""Every page in docs/ is reachable from the site's navigation, and every nav entry exists.

``mkdocs build --strict`` (make docs, .ci/run) fails on both too; this test says which page, fast,
without the docs tools installed.
"""

from __future__ import annotations

from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def nav_pages(node) -> list[str]:
    """The .md paths named anywhere in mkdocs.yml's ``nav`` (entries are str, {title: str|list} or lists)."""
    if isinstance(node, str):
        return [node] if node.endswith(".md") else []
    if isinstance(node, list):
        return [p for item in node for p in nav_pages(item)]
    if isinstance(node, dict):
        return [p for value in node.values() for p in nav_pages(value)]
    return []


def load_config() -> dict:
    # safe_load: mkdocs.yml carries no YAML tags (no !!python/name for Material's emoji), on purpose.
    return yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))


def test_config_points_at_docs():
    config = load_config()
    assert config["docs_dir"] == "docs"
    assert config["theme"]["name"] == "material"
    assert config.get("strict") is True


def test_every_docs_page_is_in_the_nav():
    in_nav = set(nav_pages(load_config()["nav"]))
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")}
    missing = sorted(pages - in_nav)
    assert not missing, f"docs pages missing from the nav in mkdocs.yml: {missing}"


def test_every_nav_entry_exists():
    absent = sorted(p for p in nav_pages(load_config()["nav"]) if not (DOCS / p).is_file())
    assert not absent, f"nav entries in mkdocs.yml without a page in docs/: {absent}"


def test_nav_has_the_pages_the_site_promises():
    titles = {next(iter(item)) for item in load_config()["nav"] if isinstance(item, dict)}
    for wanted in ("Getting started", "Connecting a DAQ", "The web page", "REST API", "IEC 61850", "Alarms",
                   "Gap diagnosis", "Studies", "Deployment and operations", "Benchmarks", "Models and estimator"):
        assert wanted in titles


def test_nav_pages_walks_nested_sections():
    nav = ["index.md", {"A": "a.md"}, {"B": [{"b1": "b/one.md"}, "b/two.md", {"ext": "https://x.org"}]}]
    assert nav_pages(nav) == ["index.md", "a.md", "b/one.md", "b/two.md"]
