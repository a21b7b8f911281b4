"""D9: /docs and /redoc use vendored Swagger UI and ReDoc, never a CDN (the browser test in
tests/web/test_pages.py renders /docs with no request to another host)."""

from __future__ import annotations

import re


def test_docs_pages_load_only_local_assets(env):
    for path, asset in (("/docs", "/static/vendor/swagger-ui/swagger-ui-bundle.js"),
                        ("/redoc", "/static/vendor/redoc/redoc.standalone.js")):
        r = env.client.get(path)
        assert r.status_code == 200 and asset in r.text
        urls = re.findall(r"""(?:src|href)=["']([^"']+)""", r.text) + re.findall(r"url: ?'([^']+)'", r.text)
        urls += re.findall(r"""(?:['"])(https?://[^'"]+)""", r.text)
        assert urls and all(u.startswith("/") for u in urls), urls
        assert "cdn.jsdelivr" not in r.text and "fonts.googleapis" not in r.text
        got = env.client.get(asset)
        assert got.status_code == 200 and len(got.content) > 100_000
    assert env.client.get("/static/vendor/swagger-ui/swagger-ui.css").status_code == 200
