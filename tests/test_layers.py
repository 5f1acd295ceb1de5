"""Module structure (DESIGN section 2): imports only downwards, no import circle.

Module-level imports only (an import inside a function or under ``TYPE_CHECKING`` runs
late and cannot form a circle at import time)."""

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "kinecal"
#: spatial <- kinematics <- optimize <- calibration <- io, report, experiments, vision <- batch,
#: cli
LAYER = {"kinematics": 1, "optimize": 2, "calibration": 3, "vision": 4, "io": 4,
         "report": 4, "experiments": 4, "batch": 5, "cli": 5, "__main__": 6}


def module_graph() -> dict[str, set[str]]:
    mods = {}
    for path in SRC.rglob("*.py"):
        parts = path.relative_to(SRC.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        mods[name] = path
    graph = {}
    for name, path in mods.items():
        deps = set()
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                    and node.module.startswith("kinecal"):
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    deps.add(sub if sub in mods else node.module)
            elif isinstance(node, ast.Import):
                deps.update(a.name for a in node.names if a.name.startswith("kinecal."))
        graph[name] = {d for d in deps if d in mods and d != name}
    return graph


def layer(module: str) -> int:
    parts = module.split(".")
    return LAYER.get(parts[1], 0) if len(parts) > 1 else 6


def test_imports_go_downwards_and_io_never_imports_calibration():
    graph = module_graph()
    assert len(graph) > 100 and "kinecal.calibration.uncertainty" in graph
    upward = [(u, v) for u, vs in graph.items() for v in vs if layer(v) > layer(u)]
    assert not upward, upward
    io_calib = [(u, v) for u, vs in graph.items() for v in vs
                if u.startswith("kinecal.io.") and v.startswith("kinecal.calibration")]
    assert not io_calib, io_calib


def test_no_import_circle():
    graph = module_graph()
    state: dict[str, int] = {}
    circles = []

    def visit(u: str, stack: list[str]) -> None:
        state[u] = 1
        stack.append(u)
        for v in sorted(graph[u]):
            if state.get(v) == 1:
                circles.append(stack[stack.index(v):] + [v])
            elif v not in state:
                visit(v, stack)
        stack.pop()
        state[u] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [])
    assert not circles, circles
