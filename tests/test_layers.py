"""Module structure (DESIGN section 7, docs/architecture.md): which package may import which,
and no import circle.

The table `ALLOWED` is read on module-level imports; a convenience method (a result's
``report()``) may import further inside the function (`LATE_ALLOWED`). The circle test reads
every import, inside functions too (a late import still ties the two modules together), except
those under ``if TYPE_CHECKING:`` (annotations only, never run)."""

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "kinecal"

#: modules of the ground floor: everything may import them
GROUND = {"spatial", "errors", "diagnostics", "_files", "_temps", "_yaml", "_limits", "data",
          "_lazy", "_special", "_reproducible", "_blas"}
#: shared helpers of every calibration kind (``kinecal.calibration.<module>``)
CALIBRATION_SHARED = {"identifiability", "uncertainty", "covariance", "method_options"}

#: which package may import which at module level (docs/architecture.md draws this table);
#: data flows read -> model -> identify -> trust -> apply -> export, imports only downwards
ALLOWED: dict[str, set[str]] = {
    "ground": set(),
    "optimize": {"ground"},
    "metrology": {"ground"},
    "datasets": {"ground"},
    "kinematics": set(),
    "kinematics.serial": {"ground"},
    "kinematics.stewart": {"ground", "optimize"},
    "kinematics.tree": {"ground", "kinematics.serial"},
    "io": {"ground", "datasets", "kinematics.serial", "kinematics.stewart", "kinematics.tree"},
    "calibration": {"ground", "optimize", "kinematics.serial"},
    "calibration.serial": {"ground", "calibration", "calibration.diagnostics",
                           "kinematics.serial", "optimize", "metrology"},
    "calibration.blocks": {"ground", "calibration", "calibration.diagnostics",
                           "calibration.serial", "kinematics.serial", "kinematics.tree",
                           "optimize", "metrology"},
    "calibration.stewart": {"ground", "calibration", "calibration.diagnostics",
                            "kinematics.stewart", "optimize", "metrology"},
    "calibration.handeye": {"ground", "calibration", "calibration.diagnostics", "optimize"},
    "calibration.camera": {"ground", "calibration", "calibration.blocks",
                           "calibration.diagnostics", "calibration.handeye",
                           "calibration.serial", "kinematics.serial", "kinematics.tree",
                           "optimize", "metrology"},
    "calibration.diagnostics": {"ground", "calibration", "calibration.serial",
                                "calibration.stewart", "calibration.handeye",
                                "kinematics.serial", "kinematics.stewart", "metrology"},
    "compensation": {"ground", "kinematics.serial", "calibration", "calibration.serial",
                     "calibration.diagnostics", "metrology"},
    "vision": {"ground", "io", "calibration", "calibration.handeye", "calibration.camera",
               "calibration.serial", "kinematics.serial", "kinematics.tree", "metrology"},
    "report": {"ground", "kinematics.serial", "kinematics.stewart", "metrology"},
    "experiments": {"ground", "optimize", "metrology", "io", "kinematics.serial",
                    "kinematics.stewart", "calibration", "calibration.serial",
                    "calibration.stewart", "calibration.handeye", "calibration.diagnostics"},
    "batch": {"ground", "io", "metrology", "calibration", "calibration.serial",
              "calibration.diagnostics"},
    "registry": {"ground", "kinematics.serial", "report"},
    "cli": {"ground", "calibration", "experiments"},
    "ui": {"ground", "io", "kinematics.serial", "kinematics.tree", "calibration",
           "calibration.serial", "datasets"},
    "__main__": {"cli"},
    "kinecal": {"ground"},
}
#: function-level imports may also reach these (a result's ``report()`` / ``to_json()``
#: helpers, the command line loading one command's module on demand)
LATE_ALLOWED: dict[str, set[str]] = {
    "calibration": {"calibration.serial"},
    "calibration.serial": {"io", "report", "kinecal", "calibration.blocks"},
    "calibration.camera": {"io", "kinecal"},
    "calibration.stewart": {"report"},
    "batch": {"calibration.serial", "calibration.blocks", "io"},
    "report": {"calibration.diagnostics", "compensation", "experiments", "vision", "kinecal"},
    "experiments": {"cli"},
    "registry": {"io", "kinecal", "optimize", "report", "metrology", "calibration",
                 "calibration.serial", "calibration.blocks", "calibration.diagnostics"},
    "cli": {"registry", "batch", "calibration.blocks", "calibration.camera",
            "calibration.diagnostics", "calibration.handeye", "calibration.serial",
            "calibration.stewart", "compensation", "datasets", "io", "kinematics.serial",
            "kinematics.stewart", "kinematics.tree", "report", "vision", "metrology",
            "kinecal", "ui"},
    "ui": {"calibration.serial", "datasets", "io", "kinematics.tree", "registry"},
}
#: below no kind of machine: compensation is the apply step on top of calibration results
NEVER = [("calibration", "compensation"), ("io", "calibration"), ("kinematics", "calibration"),
         ("kinematics", "io"), ("optimize", "kinematics")]


def _type_checking(node: ast.AST) -> bool:
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (
        (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
        or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"))


def _imports(tree: ast.Module, late: bool, annotations: bool = False) -> list[ast.AST]:
    """The import statements of a module: top level only, or (`late`) also those inside
    functions, classes and conditions, except under ``if TYPE_CHECKING:`` (unless
    `annotations`)."""
    if not late:
        return list(tree.body)
    found, todo = [], list(tree.body)
    while todo:
        node = todo.pop()
        if _type_checking(node) and not annotations:
            todo.extend(node.orelse)
            continue
        if isinstance(node, ast.Import | ast.ImportFrom):
            found.append(node)
        todo.extend(ast.iter_child_nodes(node))
    return found


def module_graph(late: bool = False, annotations: bool = False) -> dict[str, set[str]]:
    """``{module: modules it imports}`` inside kinecal (`late`: with function-level imports;
    `annotations`: with those under ``if TYPE_CHECKING:`` too)."""
    mods = {}
    for path in SRC.rglob("*.py"):
        parts = path.relative_to(SRC.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        mods[name] = path
    graph = {}
    for name, path in mods.items():
        deps = set()
        for node in _imports(ast.parse(path.read_text(encoding="utf-8")), late, annotations):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                    and node.module.startswith("kinecal"):
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    deps.add(sub if sub in mods else node.module)
            elif isinstance(node, ast.Import):
                deps.update(a.name for a in node.names if a.name.startswith("kinecal."))
        graph[name] = {d for d in deps if d in mods and d != name}
    return graph


def package(module: str) -> str:
    """The package a module belongs to in `ALLOWED`: ``kinematics.serial``,
    ``calibration.handeye``, ``io``, ..., ``ground`` for the ground floor."""
    parts = module.split(".")
    if len(parts) == 1:
        return "kinecal"
    if parts[1] in GROUND:
        return "ground"
    if parts[1] in ("kinematics", "calibration") and len(parts) > 2 \
            and parts[2] not in CALIBRATION_SHARED:
        return f"{parts[1]}.{parts[2]}"
    return parts[1]


def _crossings(graph: dict[str, set[str]], allowed) -> list[tuple[str, str]]:
    return [(u, v) for u, vs in graph.items() for v in vs
            if package(u) != package(v) and package(v) not in allowed(package(u))]


def test_every_package_is_in_the_table():
    graph = module_graph(late=True)
    assert len(graph) > 100 and "kinecal.calibration.uncertainty" in graph
    unknown = sorted({package(m) for m in graph} - set(ALLOWED))
    assert not unknown, f"add these packages to ALLOWED (and docs/architecture.md): {unknown}"


def test_imports_follow_the_table():
    bad = _crossings(module_graph(), lambda p: ALLOWED[p])
    assert not bad, bad


def test_late_imports_follow_the_table():
    bad = _crossings(module_graph(late=True),
                     lambda p: ALLOWED[p] | LATE_ALLOWED.get(p, set()))
    assert not bad, bad


def test_never_imported():
    graph = module_graph(late=True)
    bad = [(u, v) for u, vs in graph.items() for v in vs for low, high in NEVER
           if package(u).split(".")[0] == low and package(v).split(".")[0] == high]
    assert not bad, bad


def test_the_table_finds_a_violation():
    """The checks can fail: an io module importing calibration is caught."""
    graph = {"kinecal.io.models": {"kinecal.calibration.serial.api"}}
    assert _crossings(graph, lambda p: ALLOWED[p]) == [
        ("kinecal.io.models", "kinecal.calibration.serial.api")]


def test_late_imports_are_read():
    """The circle test sees imports inside functions (report.html imports the compensation
    section late) and skips those under TYPE_CHECKING (markers annotates SerialModel)."""
    late, top = module_graph(late=True), module_graph()
    assert "kinecal.report.compensation" in late["kinecal.report.html"]
    assert "kinecal.report.compensation" not in top["kinecal.report.html"]
    assert "kinecal.kinematics.serial.model" not in late["kinecal.kinematics.serial.markers"]


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


def test_the_batch_modules_import_each_other_one_way_even_for_annotations():
    """batch.jobs imports batch.job_checks, which imported jobs' Job for its annotations:
    a circle a reader (and a type checker) still follows; the checks now describe the job
    they read (a Protocol)."""
    graph = module_graph(late=True, annotations=True)
    batch = [m for m in graph if m.startswith("kinecal.batch.")]
    pairs = [(a, b) for a in batch for b in graph[a] if b in batch and a in graph[b]]
    assert not pairs, pairs


def test_no_source_text_names_an_issue_number():
    """A reader of the code has no issue tracker: docstrings and comments name the module
    or the docs page instead (another project's issue, such as OpenCV's, may be cited)."""
    import re

    pattern = re.compile(r"\bissues? ?#?\d+|\bissue \d+'s", re.IGNORECASE)
    found = [f"{p.relative_to(SRC)}:{n}: {line.strip()}"
             for p in SRC.rglob("*.py")
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             if pattern.search(line) and not re.search(r"(OpenCV|its) issue \d+", line)]
    assert not found, found
