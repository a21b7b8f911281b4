"""``Allow`` that lists every method of a path (RFC 9110 §10.2.1), and OPTIONS answered with it.

FastAPI registers one route per method, and Starlette's 405 names only the methods of the first
route whose path matches: ``PUT /temperature`` answered ``Allow: GET`` though PUT and GET exist.
This middleware reads the app's routes when (and only when) a 405 or an OPTIONS needs them.
"""

from __future__ import annotations

try:  # FastAPI >= 0.13x keeps included routers as branches; this walks them flat
    from fastapi.routing import iter_route_contexts
except ImportError:  # older FastAPI: app.routes is already flat
    def iter_route_contexts(routes):
        return iter(routes)


def allowed(app, path: str) -> list[str]:
    """Every method some route of ``app`` serves at ``path`` (HEAD with GET), sorted."""
    methods: set[str] = set()
    for route in iter_route_contexts(app.router.routes):
        route_methods, regex = getattr(route, "methods", None), getattr(route, "path_regex", None)
        if route_methods and regex is not None and regex.match(path):  # mounts and websockets have no methods
            methods |= set(route_methods)
    if "GET" in methods:
        methods.add("HEAD")
    return sorted(methods)


class AllowedMethods:
    """ASGI middleware: OPTIONS on a known path answers 204 with ``Allow``; any 405 carries the
    full ``Allow``."""

    def __init__(self, app, fastapi_app):
        self.app, self.fastapi_app = app, fastapi_app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        path, root = scope["path"], scope.get("root_path", "")
        if root and path.startswith(root):  # behind a proxy's prefix: the routes know the rest
            path = path[len(root):]
        if scope["method"] == "OPTIONS":
            methods = allowed(self.fastapi_app, path)
            if methods and "OPTIONS" not in methods:
                allow = ", ".join([*methods, "OPTIONS"]).encode()
                await send({"type": "http.response.start", "status": 204,
                            "headers": [(b"allow", allow), (b"cache-control", b"no-store")]})
                return await send({"type": "http.response.body", "body": b""})

        async def full_allow(message):
            if message["type"] == "http.response.start" and message["status"] == 405:
                methods = allowed(self.fastapi_app, path)
                if methods:
                    headers = [(k, v) for k, v in message.get("headers", []) if k.lower() != b"allow"]
                    message = {**message, "headers": [*headers, (b"allow", ", ".join(methods).encode())]}
            await send(message)

        await self.app(scope, receive, full_allow)
