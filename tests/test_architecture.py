"""The layout's rules, checked on the import graph (SPEC §2): who may import whom, no cycles, module sizes.

- ``sim`` and ``autopilot`` never import each other;
- ``mavlink_bridge.contract`` imports neither pymavlink nor any other part of the bridge;
- ``sim`` and ``autopilot`` import only the contract from the bridge, except at their I/O edges;
- only ``mavlink_bridge`` imports pymavlink;
- no import cycles between modules (a known cycle being removed is listed, and must leave the list once gone);
- no module over the size limit unless it is listed with its reason;
- packages import each other only along the arrows of ``ALLOWED_IMPORTS`` (drawn in docs/architecture.md, which the
  test reads back): the arrows form a layering, so nothing is imported upward and no subpackage imports the top
  level of its package (autopilot's composition and process edge);
- ``tools`` by role: the product's tools (its loose modules and ``tools.campaign``) above sim, autopilot and the
  bridge; the paper's research code (``tools.research``) and the benchmarks (``tools.benchmarks``) above them; the
  product (sim, autopilot, the bridge, the product's tools) never imports research, benchmarks or tests, and nothing
  under ``tools`` imports tests.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sim", "autopilot", "mavlink_bridge", "tools")
#: The rooms of ``tools`` that are not the product: the wheel leaves them out (pyproject.toml), they run from a
#: repository checkout, and nothing of the product imports them.
NOT_PRODUCT_ROOMS = frozenset({"tools.research", "tools.benchmarks"})
#: The I/O edges of sim and autopilot: they own sockets (CLI, lockstep server/loop, links) or write the lockstep's
#: wire (``sim.fleet_run``: a fleet step's datagrams, for the UDP server and the in-process campaign flight alike).
IO_EDGES = {
    "sim.cli",
    "sim.server",
    "sim.fleet_run",
    "autopilot.cli",
    "autopilot.launcher",
    "autopilot.launch_plan",
    "autopilot.launch_commands",
    "autopilot.io_loop",
}
MAX_LINES = 420
#: Modules allowed over MAX_LINES, with the reason (reviewed; keep the list short). A ratchet: a listed module
#: that shrinks under the limit must leave the list (the test says so).
LONG_MODULES: dict[str, str] = {}
#: The rooms of the layout: ``sim``; each subpackage of ``autopilot``, ``mavlink_bridge`` and ``tools``; and the top
#: level of each of those (its loose modules: autopilot's composition and process edge, the bridge's ``__init__``,
#: the product's tools: ground station, SITL test API, run commands, encounter generator, monitor, figures).
#: Room -> the rooms it may import (besides itself). Every arrow is in use (the test says when one is not) and
#: the same table is drawn in docs/architecture.md; the order below is the layering, bottom first.
ALLOWED_IMPORTS: dict[str, frozenset[str]] = {
    name: frozenset(targets)
    for name, targets in {
        "mavlink_bridge.contract": (),
        "mavlink_bridge": ("mavlink_bridge.contract",),
        "mavlink_bridge.wire": ("mavlink_bridge.contract",),
        "mavlink_bridge.lockstep": ("mavlink_bridge.contract", "mavlink_bridge.wire"),
        "mavlink_bridge.gcs_server": ("mavlink_bridge.contract", "mavlink_bridge.wire"),
        "mavlink_bridge.gcs_client": ("mavlink_bridge.contract", "mavlink_bridge.wire"),
        "sim": ("mavlink_bridge.contract", "mavlink_bridge.lockstep", "mavlink_bridge.wire"),
        "autopilot.tuning": (),
        "autopilot.estimation": ("mavlink_bridge.contract",),
        "autopilot.parameters": ("mavlink_bridge.contract",),
        "autopilot.geofence": ("mavlink_bridge.contract",),
        "autopilot.control": ("autopilot.parameters", "mavlink_bridge.contract"),
        "autopilot.flight_tasks": ("autopilot.estimation", "autopilot.parameters", "mavlink_bridge.contract"),
        "autopilot.safety": ("autopilot.estimation", "autopilot.parameters", "mavlink_bridge.contract"),
        "autopilot.planner": ("autopilot.geofence", "autopilot.parameters", "mavlink_bridge.contract"),
        "autopilot.mission": (
            "autopilot.flight_tasks", "autopilot.geofence", "autopilot.parameters", "autopilot.planner",
            "mavlink_bridge.contract",
        ),
        "autopilot.commander": (
            "autopilot.estimation", "autopilot.flight_tasks", "autopilot.parameters", "autopilot.safety",
            "mavlink_bridge.contract",
        ),
        "autopilot.traffic": (
            "autopilot.parameters", "autopilot.planner", "autopilot.safety", "mavlink_bridge.contract",
        ),
        "autopilot.navigation": (
            "autopilot.estimation", "autopilot.flight_tasks", "autopilot.geofence", "autopilot.mission",
            "autopilot.parameters", "autopilot.planner", "autopilot.safety", "autopilot.traffic",
            "mavlink_bridge.contract",
        ),
        "autopilot.flight_control": (
            "autopilot.control", "autopilot.estimation", "autopilot.flight_tasks", "autopilot.navigation",
            "autopilot.parameters",
        ),
        "autopilot.reporting": (
            "autopilot.commander", "autopilot.control", "autopilot.estimation", "autopilot.flight_control",
            "autopilot.flight_tasks", "autopilot.navigation", "autopilot.safety", "mavlink_bridge.contract",
        ),
        "autopilot.telemetry": (
            "autopilot.control", "autopilot.estimation", "autopilot.flight_tasks", "autopilot.geofence",
            "autopilot.mission", "autopilot.reporting", "mavlink_bridge.contract",
        ),
        "autopilot": (
            "autopilot.commander", "autopilot.control", "autopilot.estimation", "autopilot.flight_control",
            "autopilot.flight_tasks", "autopilot.mission", "autopilot.navigation", "autopilot.parameters",
            "autopilot.planner", "autopilot.reporting", "autopilot.safety", "autopilot.telemetry", "autopilot.traffic",
            "mavlink_bridge.contract", "mavlink_bridge.gcs_server", "mavlink_bridge.lockstep", "mavlink_bridge.wire",
        ),
        # tools: the product's tools, then the campaigns over them; research and benchmarks on top
        "tools": (  # autopilot.control and .traffic: tools.warm_jit compiles their batch and ORCA kernels at setup
            "autopilot", "autopilot.control", "autopilot.estimation", "autopilot.mission", "autopilot.telemetry",
            "autopilot.traffic", "mavlink_bridge.contract", "mavlink_bridge.gcs_client", "mavlink_bridge.lockstep",
            "mavlink_bridge.wire", "sim",
        ),
        "tools.gcs": (
            "autopilot.mission", "mavlink_bridge.contract", "mavlink_bridge.gcs_client", "mavlink_bridge.wire",
        ),
        "tools.run": ("autopilot", "autopilot.estimation", "autopilot.mission", "sim"),
        "tools.campaign": (
            "autopilot", "autopilot.commander", "autopilot.control", "autopilot.estimation", "autopilot.mission",
            "autopilot.parameters", "autopilot.telemetry", "mavlink_bridge.contract", "mavlink_bridge.gcs_client",
            "mavlink_bridge.lockstep", "mavlink_bridge.wire", "sim", "tools", "tools.gcs",
        ),
        "tools.research": (
            "autopilot", "autopilot.control", "autopilot.estimation", "autopilot.flight_tasks", "autopilot.mission",
            "autopilot.tuning", "mavlink_bridge.contract", "mavlink_bridge.lockstep", "sim", "tools.campaign",
        ),
        "tools.benchmarks": (
            "autopilot", "autopilot.commander", "autopilot.control", "autopilot.estimation", "autopilot.flight_tasks",
            "autopilot.geofence", "autopilot.mission", "autopilot.navigation", "autopilot.planner",
            "autopilot.reporting", "autopilot.telemetry", "autopilot.traffic", "mavlink_bridge.contract",
            "mavlink_bridge.gcs_client",
            "mavlink_bridge.gcs_server", "mavlink_bridge.lockstep", "mavlink_bridge.wire", "sim", "tools",
            "tools.campaign", "tools.research",
        ),
    }.items()
}  # fmt: skip
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


def _room(module: str) -> str:
    """The room of a module (see ALLOWED_IMPORTS): ``sim``, a subpackage, or the top level of its package."""
    parts = module.split(".")
    if parts[0] == "sim" or len(parts) == 1:
        return parts[0]
    if len(parts) == 2 and MODULES[module].name != "__init__.py":
        return parts[0]  # a loose module at the top level
    return ".".join(parts[:2])


def _room_arrows() -> dict[str, set[str]]:
    arrows: dict[str, set[str]] = {}
    for module, deps in GRAPH.items():
        arrows.setdefault(_room(module), set()).update(_room(d) for d in deps if _room(d) != _room(module))
    return arrows


def test_packages_import_each_other_only_along_the_allowed_arrows() -> None:
    arrows = _room_arrows()
    unknown = set(arrows) - set(ALLOWED_IMPORTS)
    assert not unknown, f"new packages {sorted(unknown)}: give each its arrows in ALLOWED_IMPORTS and the drawing"
    bad = sorted(
        (module, dep)
        for module, deps in GRAPH.items()
        for dep in deps
        if _room(dep) != _room(module) and _room(dep) not in ALLOWED_IMPORTS[_room(module)]
    )
    assert not bad, f"imports outside the allowed arrows (move the code, or argue for the arrow): {bad}"
    unused = sorted((room, target) for room, targets in ALLOWED_IMPORTS.items() for target in targets - arrows[room])
    assert not unused, f"allowed arrows no module uses any more: remove them here and in the drawing: {unused}"


def test_the_allowed_arrows_are_layers_nothing_imported_upward() -> None:
    placed: set[str] = set()
    for room, targets in ALLOWED_IMPORTS.items():  # listed bottom first: each room imports only rooms below it
        assert targets <= placed, f"{room} imports {sorted(targets - placed)}, which are not below it"
        placed.add(room)
    for room, targets in ALLOWED_IMPORTS.items():  # a package's top level is above all its subpackages
        top = room.split(".")[0]
        if top == "tools":
            continue  # tools' top level composes nothing: it is the product's tools, which the campaigns fly
        assert top == room or top not in targets, f"{room} imports the top level of {top}"


def test_the_drawing_in_the_docs_shows_the_allowed_arrows() -> None:
    text = (ROOT / "docs" / "architecture.md").read_text()
    block = text.split("<!-- allowed-imports: checked by tests/test_architecture.py -->", 1)[1]
    block = block.split("```text\n", 1)[1].split("```", 1)[0]
    drawn = {}
    for line in block.splitlines():
        room, _, targets = line.partition(" -> ")
        drawn[room.strip()] = frozenset(t.strip() for t in targets.split(",") if t.strip() not in ("", "(nothing)"))
    assert drawn == ALLOWED_IMPORTS, "docs/architecture.md draws other arrows than ALLOWED_IMPORTS"


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
    real = {frozenset(c) for c in cycles if not all((m in MODULES and MODULES[m].name == "__init__.py") or any(
        other.startswith(m + ".") for other in c) for m in c)}  # fmt: skip
    assert not real, f"import cycles: {sorted(sorted(c) for c in real)}"


def test_the_product_never_imports_research_benchmarks_or_tests() -> None:
    tests = ROOT / "tests"  # its helpers are imported by their own names (tests/ is on sys.path in a test run)
    test_helpers = {"tests", *(p.stem for p in tests.glob("*.py"))}
    test_helpers |= {p.parent.name for p in tests.glob("*/__init__.py")}
    for module, path in MODULES.items():
        imported = _imports(path)
        bad = sorted(name for name in imported if name.split(".")[0] in test_helpers)
        assert not bad, f"{module} imports test code {bad}: move what it needs out of tests/"
        if _room(module) in NOT_PRODUCT_ROOMS:
            continue
        bad = sorted(name for name in imported if any(name == r or name.startswith(r + ".") for r in NOT_PRODUCT_ROOMS))
        assert not bad, f"{module} (product) imports {bad}, which the wheel does not ship"
        if _top(module) != "tools":
            bad = sorted(name for name in imported if name.split(".")[0] == "tools")
            assert not bad, f"{module} imports tools {bad}: sim, autopilot and the bridge stand below the tools"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_module_size(module: str) -> None:
    lines = len(MODULES[module].read_text().splitlines())
    if module in LONG_MODULES:
        assert lines > MAX_LINES, f"{module} has {lines} lines now: remove it from LONG_MODULES"
        return
    assert lines <= MAX_LINES, f"{module} has {lines} lines (> {MAX_LINES}): split it or list it with a reason"
