"""The import graph of ``motionlab/``, built from the source (ast): no cycle, and no module
imports from a layer above its own (the layer order is docs/architecture.md's "Layers").

Imports under ``if TYPE_CHECKING:`` are left out (they never run); imports inside functions
count (they run, later). Importing ``a.b.c`` imports the package ``a.b`` too, so a submodule
that imports its own package's ``__init__`` while that imports the submodule is a cycle.
"""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

from conftest import ROOT

PACKAGE = ROOT / "motionlab"

#: lowest first; a module belongs to the longest entry that is it or a package holding it
LAYERS: tuple[tuple[str, ...], ...] = (
    # 0 base: errors, units, files, quaternions, the tables of joints and segments
    (
        "motionlab.errors",
        "motionlab.units",
        "motionlab.atomic",
        "motionlab.yamlsafe",
        "motionlab.lock",
        "motionlab.isolated",
        "motionlab.quat_kernels",
        "motionlab.dsp",
        "motionlab.rotations",
        "motionlab.lineage",
        "motionlab.plain",
        "motionlab.minpack",
        "motionlab.kinematics.joint_types",
        "motionlab.kinematics.segment_types",
        "motionlab.kinematics.joint_angles",
    ),
    # 1 data: the typed results, the session and its file, the protocol, the time base, the
    # session bound to the protocol
    (
        "motionlab.results",
        "motionlab.clocknet",
        "motionlab.session",
        "motionlab.timebase",
        "motionlab.qc",
        "motionlab.protocol",
        "motionlab.sensor_map",
        "motionlab.summary",
        "motionlab.binding",
    ),
    # 2 ingest and sync: the readers, the assembly of a session, the IMUs' clocks
    ("motionlab.io", "motionlab.ingest", "motionlab.clocksync"),
    # 3 fuse: sensor calibrations and orientation estimators
    ("motionlab.sensorcal", "motionlab.fusion"),
    # 4 calibrate: sensor-to-segment calibration
    ("motionlab.segments",),
    # 5 angles, metrics and gait
    ("motionlab.kinematics",),
    # 6 validate against a reference; marker-aided fusion reads the optical reference
    ("motionlab.validation", "motionlab.fusion.marker_registration"),
    # 7 the stages, reports, exports and the simulator
    ("motionlab.stages", "motionlab.report", "motionlab.export", "motionlab.simulate"),
    # 8 the whole run and studies
    ("motionlab.pipeline", "motionlab.batch"),
    # 9 the command line
    ("motionlab.cli", "motionlab.__main__"),
)

#: cycles and upward imports allowed for now, each as (importer, imported): none are left
#: (issue #24, item 1). An entry added here must say why and leave when its import is gone.
KNOWN: set[tuple[str, str]] = set()


@cache
def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(ROOT).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _owner(name: str, modules: dict[str, Path]) -> str | None:
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def _imports(module: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The motionlab modules ``module`` imports (and their packages), TYPE_CHECKING aside."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                for other in child.orelse:
                    visit(other)
                continue
            names: list[str] = []
            if isinstance(child, ast.Import):
                names = [a.name for a in child.names]
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    up = package.split(".")[: len(package.split(".")) - child.level + 1]
                    base = ".".join(up + ([base] if base else []))
                names = [f"{base}.{a.name}" for a in child.names]
            for name in names:
                target = _owner(name, modules)
                if target and target != module:
                    found.add(target)  # what is named, even the module's own package
                while target and "." in target:  # and the packages it runs, unless they
                    target = target.rpartition(".")[0]  # hold the module (run before it)
                    if not module.startswith(target + "."):
                        found.add(target)
            visit(child)

    visit(ast.parse(path.read_text(encoding="utf-8")))
    return {t for t in found if t in modules and t != module}


@cache
def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {m: _imports(m, p, modules) for m, p in modules.items()}


def _layer(module: str) -> int:
    """The layer of ``module``: that of the longest :data:`LAYERS` entry holding it."""
    found = [
        (len(g), i)
        for i, group in enumerate(LAYERS)
        for g in group
        if module == g or module.startswith(g + ".")
    ]
    assert found, f"{module} is in no layer: add it to LAYERS and docs/architecture.md"
    return max(found)[1]


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph.get(v, ()):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return out


def test_no_import_cycle():
    graph = _graph()
    cut = {m: {t for t in ts if (m, t) not in KNOWN} for m, ts in graph.items()}
    assert _cycles(cut) == []
    for edge in KNOWN:  # a known exception that is gone leaves the list too
        assert edge[1] in graph[edge[0]], f"{edge} is no longer imported: remove it from KNOWN"


def test_no_import_from_a_higher_layer():
    """Upward imports are refused; a package whose ``__init__`` imports nothing of motionlab
    (``kinematics``: a docstring) is in no layer: importing its submodules runs it, harmlessly."""
    graph, modules = _graph(), _modules()
    empty = {m for m, p in modules.items() if p.name == "__init__.py" and not graph[m]}
    upward = sorted(
        (m, t, _layer(m), _layer(t))
        for m, ts in graph.items()
        for t in ts
        if t not in empty and _layer(t) > _layer(m) and (m, t) not in KNOWN
    )
    assert upward == []


def test_the_graph_sees_function_local_and_skips_type_checking_imports():
    graph = _graph()
    assert "motionlab.validation.figures" in graph["motionlab.report.pages_validation"]  # local
    assert "motionlab.fusion.markers" not in graph["motionlab.fusion.timegrid"]  # TYPE_CHECKING
    assert "motionlab.kinematics.joint_types" in graph["motionlab.protocol"]
