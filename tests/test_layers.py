"""Imports point down the layers, and no two packages import each other (docs/architecture.md).

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
     "service.arguments", "service.processes"),
    ("service.mechanics",),                                      # the paper's reduced physics
    ("drivers", "service.breaker_file", "service.breaker_travel", "service.acquisition"),  # captures, DAQs, breaker files
    ("service.estimation", "service.storage", "service.alarms", "service.prototypes"),
    ("service.diagnosis", "service.studies"),
    ("service.jobs", "service.workers", "service.refit", "service.agent", "service.iec61850",
     "service.settings"),
    ("service.api", "service.web", "service.cli"),
]
LAYER = {pkg: i for i, pkgs in enumerate(LAYERS) for pkg in pkgs}
# Each package's ``commands.py`` is a subcommand of ``hvcb`` (service/cli.py imports it by name):
# the command-line edge, where settings are read. It counts as part of service.cli.
CLI = "service.cli"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
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


def imports_of(path: Path) -> list[tuple[str, int]]:
    module = module_name(path)
    is_pkg = path.name == "__init__.py"
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".") if is_pkg else module.split(".")[:-1]
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            # ``from pkg import sub`` may name a submodule: count ``pkg.sub`` when it exists.
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                sub_path = ROOT.joinpath(*sub.split("."))
                found.append((sub if sub_path.with_suffix(".py").exists() or sub_path.is_dir() else target,
                              node.lineno))
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
    # Tarjan's strongly connected components: any component of more than one package is a cycle.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
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

    for v in sorted(LAYER):
        if v not in index:
            visit(v)
    detail = ["{}: {}".format(" <-> ".join(c), "; ".join(s for (a, b), sites in edges.items()
                                                         if a in c and b in c for s in sites)) for c in cycles]
    assert not cycles, "import cycles between packages:\n" + "\n".join(detail)


@pytest.mark.parametrize("module,expected", [("drivers.commands", CLI), ("service.refit.commands", CLI),
                                             ("service.mechanics.opening", "service.mechanics"),
                                             ("drivers.comtrade.reader", "drivers"), ("numpy", None)])
def test_package_of(module, expected):
    assert package_of(module) == expected


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
