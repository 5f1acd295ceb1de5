"""Module structure (DESIGN section 2): imports only downwards, no import circle.

The layering test reads module-level imports (a convenience method such as
``CalibrationResult.report`` may import an upper layer inside the function). The circle test
reads every import, inside functions too (a late import still ties the two modules
together), except those under ``if TYPE_CHECKING:`` (annotations only, never run)."""

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "kinecal"
#: spatial <- kinematics <- optimize <- calibration <- io, report, experiments, vision <- batch,
#: cli
LAYER = {"kinematics": 1, "optimize": 2, "calibration": 3, "vision": 4, "io": 4,
         "report": 4, "experiments": 4, "batch": 5, "cli": 5, "__main__": 6}


def _type_checking(node: ast.AST) -> bool:
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (
        (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
        or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"))


def _imports(tree: ast.Module, late: bool) -> list[ast.AST]:
    """The import statements of a module: top level only, or (`late`) also those inside
    functions, classes and conditions, except under ``if TYPE_CHECKING:``."""
    if not late:
        return list(tree.body)
    found, todo = [], list(tree.body)
    while todo:
        node = todo.pop()
        if _type_checking(node):
            todo.extend(node.orelse)
            continue
        if isinstance(node, ast.Import | ast.ImportFrom):
            found.append(node)
        todo.extend(ast.iter_child_nodes(node))
    return found


def module_graph(late: bool = False) -> dict[str, set[str]]:
    """``{module: modules it imports}`` inside kinecal (`late`: with function-level imports)."""
    mods = {}
    for path in SRC.rglob("*.py"):
        parts = path.relative_to(SRC.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        mods[name] = path
    graph = {}
    for name, path in mods.items():
        deps = set()
        for node in _imports(ast.parse(path.read_text(encoding="utf-8")), late):
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


def test_late_imports_are_read():
    """The circle test sees imports inside functions (report.html imports the compensation
    section late) and skips those under TYPE_CHECKING (markers annotates SerialModel)."""
    late, top = module_graph(late=True), module_graph()
    assert "kinecal.report.compensation" in late["kinecal.report.html"]
    assert "kinecal.report.compensation" not in top["kinecal.report.html"]
    assert "kinecal.kinematics.serial" not in late["kinecal.kinematics.markers"]


def test_no_import_circle():
    graph = module_graph(late=True)
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
