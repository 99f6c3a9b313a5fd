"""The house's floors: no import loops in pipeline/ and no floor importing one above it.

The graph counts every import of a pipeline module, at the top of a file or inside a function (a
function-level import hides a loop from Python, not from the reader), and is built from the
source with ``ast``: nothing is imported to build it.
"""

from __future__ import annotations

import ast
from pathlib import Path

PIPELINE = Path(__file__).resolve().parents[1] / "pipeline"


def module_name(path: Path) -> str:
    parts = path.relative_to(PIPELINE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(tree: ast.AST, modules) -> set[str]:
    """The pipeline modules a parsed file imports, at the top or inside functions."""
    targets = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("pipeline"):
            for alias in node.names:  # `from pipeline.x import y` names module x.y when y is one
                child = f"{node.module}.{alias.name}"
                targets.add(child if child in modules else node.module)
        elif isinstance(node, ast.Import):
            targets.update(a.name for a in node.names if a.name.startswith("pipeline"))
    return {t for t in targets if t in modules}


def import_graph() -> dict[str, set[str]]:
    modules = {module_name(p): p for p in PIPELINE.rglob("*.py")}
    return {name: imported(ast.parse(path.read_text()), modules) - {name} for name, path in modules.items()}


def loops(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
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
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_loop_finder_finds_a_loop_through_three_modules() -> None:
    assert loops({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert loops({"a": {"b"}, "b": set()}) == []


def test_pipeline_has_no_import_loops() -> None:
    assert loops(import_graph()) == []


def test_the_ingest_floor_imports_nothing_above_it() -> None:
    # ingest (download, trim, media) sits on core alone; segment proposal, which detects people, is
    # above the pose floor (pipeline/pose/propose.py).
    graph = import_graph()
    uphill = {m: sorted(t for t in targets if not t.startswith(("pipeline.core", "pipeline.ingest")))
              for m, targets in graph.items() if m.startswith("pipeline.ingest")}
    assert {m: t for m, t in uphill.items() if t} == {}


# A file contract (schema, reader, writer) stands on core and on the contracts it builds on, so a stage
# that only reads a file does not import the code that computes it.
CONTRACTS = ("pipeline.pose.pose2dfile", "pipeline.pose.trackfile", "pipeline.pose.proposed",
             "pipeline.annotate.clipfile", "pipeline.motion.motionfile", "pipeline.motion.world.worldfile",
             "pipeline.music.featurefile")
# The world file's rotations follow the BVH skeleton's joint order, which is defined with the solver.
SKELETON_TABLES = {"pipeline.motion.world.worldfile": {"pipeline.motion.world.rotations"}}


def test_a_file_contract_imports_only_core_and_other_contracts() -> None:
    graph = import_graph()
    computed = {m: sorted(t for t in graph[m] - SKELETON_TABLES.get(m, set())
                          if not t.startswith("pipeline.core") and t not in CONTRACTS) for m in CONTRACTS}
    assert {m: t for m, t in computed.items() if t} == {}
