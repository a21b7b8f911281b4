"""Imports point down the layers, no two packages import each other, no two files import each other
(not even through others), and no private name is imported from another package
(docs/architecture.md).

The import graph is read from the source with ``ast`` (every ``import`` statement, including the
lazy ones inside functions), so the check needs nothing installed and runs in a second.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# Low -> high. A module may import its own package, anything in its own layer (without a cycle
# between packages) and anything lower. Keep in step with docs/architecture.md.
LAYERS: list[tuple[str, ...]] = [
    ("service.errors", "service.progress", "service.plots", "service.durable", "service.decimation",
     "service.arguments", "service.processes", "service.findings"),
    ("service.mechanics",),                                      # the paper's reduced physics
    ("drivers", "service.breaker_file", "service.breaker_travel", "service.breaker_limits",
     "service.acquisition", "service.display", "service.vibration"),  # captures, DAQs, breaker files; numbers and names in words
    ("service.estimation", "service.storage", "service.alarms", "service.prognosis", "service.prototypes"),
    ("service.diagnosis", "service.studies", "service.notifications"),
    ("service.jobs", "service.workers", "service.refit", "service.agent", "service.iec61850",
     "service.settings", "service.reports"),
    ("service.api", "service.web", "service.cli"),
]
LAYER = {pkg: i for i, pkgs in enumerate(LAYERS) for pkg in pkgs}
# Each package's ``commands.py`` is a subcommand of ``hvcb`` (service/cli.py imports it by name):
# the command-line edge, where settings are read. It counts as part of service.cli.
CLI = "service.cli"


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_of(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] == "drivers":
        return CLI if parts[-1] == "commands" else "drivers"
    if parts[0] != "service" or len(parts) < 2:
        return None
    if parts[-1] == "commands":
        return CLI
    return "service." + parts[1]


def imports_of(path: Path, root: Path = ROOT) -> list[tuple[str, int]]:
    module = module_name(path, root)
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            found += [(target, node.lineno) for _, target in imports_of_node(module, path, node, root)]
    return found


def imports_of_node(module: str, path: Path, node: ast.ImportFrom, root: Path = ROOT) -> list[tuple[str, str]]:
    """(name, module it comes from) for each name of a ``from ... import`` in ``module``."""
    if node.level:
        base = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
        base = base[:len(base) - node.level + 1]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    found = []
    # ``from pkg import sub`` may name a submodule: count ``pkg.sub`` when it exists.
    for alias in node.names:
        sub = f"{target}.{alias.name}"
        sub_path = root.joinpath(*sub.split("."))
        found.append((alias.name, sub if sub_path.with_suffix(".py").exists() or sub_path.is_dir() else target))
    return found


def package_edges() -> dict[tuple[str, str], list[str]]:
    edges: dict[tuple[str, str], list[str]] = defaultdict(list)
    for top in ("service", "drivers"):
        for path in sorted((ROOT / top).rglob("*.py")):
            src = package_of(module_name(path))
            for target, line in imports_of(path):
                dst = package_of(target)
                if dst and src and dst != src:
                    edges[(src, dst)].append(f"{path.relative_to(ROOT)}:{line} imports {target}")
    return {k: sorted(set(v)) for k, v in edges.items()}


def strongly_connected(graph: dict[str, set[str]], nodes) -> list[list[str]]:
    """Tarjan's strongly connected components of more than one node: each one is an import cycle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in nodes:
        if v not in index:
            visit(v)
    return cycles


def source_files(root: Path = ROOT) -> dict[str, Path]:
    """Every module of the project's code under ``root``, by its dotted name."""
    return {module_name(p, root): p for top in ("service", "drivers") for p in sorted((root / top).rglob("*.py"))}


def file_edges(root: Path = ROOT) -> dict[str, dict[str, int]]:
    """Module -> {imported module of the project: line}: the file-level import graph (a name imported
    from a package counts as its ``__init__``)."""
    files = source_files(root)
    edges: dict[str, dict[str, int]] = {}
    for module, path in files.items():
        edges[module] = {}
        for target, line in imports_of(path, root):
            parts = target.split(".")
            while parts and ".".join(parts) not in files:
                parts.pop()
            dst = ".".join(parts)
            if dst and dst != module:
                edges[module].setdefault(dst, line)
    return edges


def file_cycles(root: Path = ROOT) -> list[str]:
    """Each circle of imports between files, with the import lines that close it."""
    edges = file_edges(root)
    found = []
    for comp in strongly_connected({m: set(d) for m, d in edges.items()}, sorted(edges)):
        sites = [f"{a}:{edges[a][b]} imports {b}" for a in comp for b in sorted(edges[a]) if b in comp]
        found.append(" <-> ".join(comp) + ": " + "; ".join(sites))
    return found


def private_imports(root: Path = ROOT) -> list[str]:
    """``from x import _name`` where ``x`` lies in another package than the importing file."""
    found = []
    for module, path in source_files(root).items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if not isinstance(node, ast.ImportFrom):
                continue
            target = dict(imports_of_node(module, path, node, root))
            for alias in node.names:
                if alias.name.startswith("_") and not alias.name.startswith("__"):
                    src = target[alias.name]
                    if package_of(src) != package_of(module):
                        found.append(f"{path.relative_to(root)}:{node.lineno} imports {alias.name} from {src}")
    return found


def test_every_package_has_a_layer():
    packages = {package_of(module_name(p)) for top in ("service", "drivers")
                for p in (ROOT / top).rglob("*.py")} - {None, "service"}
    missing = sorted(p for p in packages if p not in LAYER)
    assert not missing, f"packages without a layer (add them to LAYERS and docs/architecture.md): {missing}"


def test_no_import_runs_up_the_layers():
    upward = [f"{where}  ({src} is layer {LAYER[src]}, {dst} is layer {LAYER[dst]})"
              for (src, dst), sites in package_edges().items() if LAYER[dst] > LAYER[src] for where in sites]
    assert not upward, "imports from a lower layer to a higher one:\n" + "\n".join(upward)


def test_no_import_cycle_between_packages():
    edges = package_edges()
    graph: dict[str, set[str]] = defaultdict(set)
    for src, dst in edges:
        graph[src].add(dst)
    cycles = strongly_connected(graph, sorted(LAYER))
    detail = ["{}: {}".format(" <-> ".join(c), "; ".join(s for (a, b), sites in edges.items()
                                                         if a in c and b in c for s in sites)) for c in cycles]
    assert not cycles, "import cycles between packages:\n" + "\n".join(detail)


@pytest.mark.parametrize("module,expected", [("drivers.commands", CLI), ("service.refit.commands", CLI),
                                             ("service.mechanics.opening", "service.mechanics"),
                                             ("drivers.comtrade.reader", "drivers"), ("numpy", None)])
def test_package_of(module, expected):
    assert package_of(module) == expected


def test_no_import_cycle_between_files():
    cycles = file_cycles()
    assert not cycles, "import cycles between files (move what both need into a third module):\n" + "\n".join(cycles)


def test_no_private_name_imported_from_another_package():
    found = private_imports()
    assert not found, "private names imported across packages (make them public or move them):\n" + "\n".join(found)


def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return tmp_path


def test_a_made_up_circle_between_files_is_found(tmp_path):
    """Three files in a ring, one import lazy inside a function: the check names all three."""
    root = _tree(tmp_path, {
        "service/__init__.py": "",
        "service/web/__init__.py": "",
        "service/web/a.py": "from .b import x\n",
        "service/web/b.py": "from service.web import c\nx = 1\n",
        "service/web/c.py": "def f():\n    from .a import x\n    return x\n",
        "service/web/d.py": "from .a import x\n",  # on the ring's edge, not in it
        "drivers/__init__.py": "",
    })
    (cycle,) = file_cycles(root)
    assert cycle.startswith("service.web.a <-> service.web.b <-> service.web.c: ")
    assert "service.web.c:2 imports service.web.a" in cycle and "service.web.d" not in cycle


def test_a_made_up_private_import_across_packages_is_found(tmp_path):
    root = _tree(tmp_path, {
        "service/__init__.py": "",
        "service/web/__init__.py": "",
        "service/web/page.py": "from service.storage.crud import _helper, public\nfrom .render import _own\n",
        "service/web/render.py": "_own = 1\n",
        "service/storage/__init__.py": "",
        "service/storage/crud.py": "def _helper(): ...\ndef public(): ...\n",
        "drivers/__init__.py": "",
    })
    assert private_imports(root) == ["service/web/page.py:1 imports _helper from service.storage.crud"]


# The prototypes are test instruments (issue 29): production code must not depend on them, or
# editing a generator would silently change the model it is evaluated with. Only the studies and
# the demo's synthetic histories run them.
PROTOTYPE_USERS = ("service.prototypes", "service.studies", "service.api.demo")


def test_production_code_never_imports_the_prototypes():
    bad = []
    for path in sorted((ROOT / "service").rglob("*.py")):
        module = module_name(path)
        if any(module == u or module.startswith(u + ".") for u in PROTOTYPE_USERS):
            continue
        bad += [f"{path.relative_to(ROOT)}:{line} imports {target}" for target, line in imports_of(path)
                if target == "service.prototypes" or target.startswith("service.prototypes.")]
    assert not bad, "production code imports a prototype (a test instrument):\n" + "\n".join(bad)
