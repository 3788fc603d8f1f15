"""The layout's rules, checked on the import graph (SPEC §2): who may import whom, no cycles, module sizes.

- ``sim`` and ``autopilot`` never import each other;
- ``mavlink_bridge.contract`` imports neither pymavlink nor any other part of the bridge;
- ``sim`` and ``autopilot`` import only the contract from the bridge, except at their I/O edges;
- only ``mavlink_bridge`` imports pymavlink;
- no import cycles between modules of the product;
- no product module over the size limit unless it is listed with its reason.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sim", "autopilot", "mavlink_bridge")
#: The I/O edges of sim and autopilot: they own sockets (CLI, lockstep server/loop, links).
IO_EDGES = {
    "sim.cli",
    "sim.server",
    "sim.fleet_server",
    "autopilot.cli",
    "autopilot.launcher",
    "autopilot.fleet_launcher",
    "autopilot.io_loop",
}
MAX_LINES = 420
#: Modules allowed over MAX_LINES, with the reason (reviewed; keep the list short). A ratchet: a listed module
#: that shrinks under the limit must leave the list (the test says so).
LONG_MODULES: dict[str, str] = {
    "autopilot.commander": (
        "one state machine (mode, arming, hold/takeoff/land/RTL points) that commands, failsafes and the per-mode "
        "targets all read and write; the land detector is its own module, the flight-task targets are next"
    ),
    "autopilot.planner.detour": (
        "the detour search: candidate generation, fence/altitude/obstacle checks and scoring over shared geometry; "
        "its types and path shapes are split out, the search itself is next"
    ),
}
#: Bridge internals still imported outside the I/O edges (a ratchet, like LONG_MODULES).
KNOWN_BRIDGE_IMPORTS: set[tuple[str, str]] = set()


def _modules() -> dict[str, Path]:
    out = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = path
    return out


MODULES = _modules()
MODULE_NAMES = frozenset(MODULES)


def _imports(path: Path) -> set[str]:
    """Every module imported anywhere in the file (also inside functions and TYPE_CHECKING blocks)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            submodules = {f"{node.module}.{alias.name}" for alias in node.names} & MODULE_NAMES
            names.update(submodules or {node.module})  # `from pkg import mod` depends on mod, not on pkg
    return names


def _product_imports(module: str) -> set[str]:
    """The product modules ``module`` imports (a name that is an attribute, not a module, maps to its module)."""
    out = set()
    for name in _imports(MODULES[module]):
        while name and name not in MODULES:
            name = name.rpartition(".")[0]
        if name and name != module:
            out.add(name)
    return out


GRAPH = {module: _product_imports(module) for module in MODULES}


def _top(module: str) -> str:
    return module.split(".")[0]


def test_sim_and_autopilot_never_import_each_other() -> None:
    bad = [(m, d) for m, deps in GRAPH.items() for d in deps if {_top(m), _top(d)} == {"sim", "autopilot"}]
    assert not bad, f"sim and autopilot import each other: {bad}"


def test_the_contract_imports_nothing_of_the_bridge_and_no_pymavlink() -> None:
    for module, path in MODULES.items():
        if not module.startswith("mavlink_bridge.contract"):
            continue
        deps = {d for d in GRAPH[module] if not d.startswith("mavlink_bridge.contract")}
        assert not deps, f"{module} imports {deps}"
        assert not any(name.startswith("pymavlink") for name in _imports(path)), module


def test_sim_and_autopilot_take_only_the_contract_from_the_bridge_except_at_their_io_edges() -> None:
    bad = []
    for module, deps in GRAPH.items():
        if _top(module) in ("sim", "autopilot") and module not in IO_EDGES:
            bridge = [d for d in deps if _top(d) == "mavlink_bridge" and not d.startswith("mavlink_bridge.contract")]
            bad += [(module, d) for d in bridge]
    assert set(bad) <= KNOWN_BRIDGE_IMPORTS, f"bridge internals imported outside the I/O edges: {bad}"
    assert set(bad) >= KNOWN_BRIDGE_IMPORTS, "KNOWN_BRIDGE_IMPORTS lists an import that is gone: remove it"


def test_only_the_bridge_imports_pymavlink() -> None:
    for top in ("sim", "autopilot", "tools"):
        for path in sorted((ROOT / top).rglob("*.py")):
            assert not any(name.startswith("pymavlink") for name in _imports(path)), path


def test_no_import_cycles() -> None:
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(node: str) -> None:  # Tarjan's strongly connected components
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for dep in GRAPH[node]:
            if dep not in index:
                visit(dep)
                low[node] = min(low[node], low[dep])
            elif dep in on_stack:
                low[node] = min(low[node], index[dep])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for module in GRAPH:
        if module not in index:
            visit(module)
    # a package's __init__ re-exporting its modules is not a cycle of behaviour
    real = [c for c in cycles if not all((m in MODULES and MODULES[m].name == "__init__.py") or any(
        other.startswith(m + ".") for other in c) for m in c)]  # fmt: skip
    assert not real, f"import cycles: {real}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_module_size(module: str) -> None:
    lines = len(MODULES[module].read_text().splitlines())
    if module in LONG_MODULES:
        assert lines > MAX_LINES, f"{module} has {lines} lines now: remove it from LONG_MODULES"
        return
    assert lines <= MAX_LINES, f"{module} has {lines} lines (> {MAX_LINES}): split it or list it with a reason"
