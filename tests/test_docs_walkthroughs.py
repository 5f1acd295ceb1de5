"""Every walkthrough of docs/*.md runs as written: each page in a fresh scratch folder, its
blocks in order, and the output the page shows is the output the commands print.

What the test reads (the conventions are also in docs/index.md, "Every page is run"):

* a ```` ```sh ```` (or ``bash``, ``shell``) block is a script: it runs through
  ``bash -e -o pipefail`` with this checkout's ``kinecal`` (and ``python``) first on the
  PATH; it must exit 0;
* a ```` ```console ```` block holds ``$ command`` lines, each followed by the output it
  prints (stdout and stderr together); each command runs through bash, and a ``kinecal``
  command must exit 0, or 2 when its output shows a ``kinecal: error:`` line (a command
  ending in ``echo $?`` shows its status itself);
* a ```` ```python ```` block runs as a script with this checkout's Python (forked from the
  server below, like the commands);
* a ```` ```text ```` block right after a sh or python block (nothing between them, or
  prose whose last line ends with a colon: "... prints:"; no heading) is that block's
  expected output;
* any other block (``yaml``, ``json``, ``csv``, ``text`` elsewhere) is shown, not run. A
  block without a language is refused: every block says what it is.

Output is compared line by line: whitespace runs may differ in length; numbers match to
the digits shown (one unit of the last shown digit, digits beyond the tenth significant
one ignored; whole numbers exactly; two numbers below 1e-9 in magnitude, round-off, are
equal); a duration (a number followed by `` s``)
is not compared; ``...`` inside a line matches any text, and a line that is only ``...``
any number of lines (output that varies, or is shortened on the page).

Markers (HTML comments, invisible on the rendered page) say what cannot run here, always
with the reason, and the test reports them:

* ``<!-- docs-test: skip REASON -->`` just before a block: the block is not run;
* ``<!-- docs-test: skip-page REASON -->`` anywhere: the page is not run (a pytest skip;
  a page whose walkthrough another test runs names that test, which must name the page);
* ``<!-- docs-test: requires MODULE[,MODULE...] REASON -->`` before a block, or
  ``requires-page`` anywhere: run only where those modules import, else skipped with the
  reason;
* ``<!-- docs-test: import-only REASON -->`` before a python block: compiled and its
  imports checked, not run (an API synopsis with names defined elsewhere).

Pages are found by globbing docs/*.md, so a new page is covered the day it lands, and run
two at a time (the machine's cores). The ``kinecal`` of the walkthroughs is the client of
tests/docs_server.py, which forks every command from one process that has imported
kinecal already (each command still in a process of its own); ``KINECAL_DOCS_PLAIN=1`` runs
each in a fresh interpreter instead. The README's tutorial is run by
tests/test_readme_tutorial.py; its other blocks are run here.
"""

from __future__ import annotations

import ast
import importlib.util
import math
import os
import re
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"
#: the kinecal that forks each command from a process with kinecal imported
SERVER = Path(__file__).with_name("docs_server.py")
#: the README section tests/test_readme_tutorial.py runs
README_TUTORIAL = "## A five-minute tutorial"

SHELL = {"sh", "bash", "shell"}
RUN = SHELL | {"console", "python"}
#: a page's blocks run with this much wall time each at most
TIMEOUT = 900
#: pages run at the same time
WORKERS = 2

NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
MARKER = re.compile(r"<!--\s*docs-test:\s*([a-z-]+)\s*(.*?)\s*-->", re.S)
FENCE = re.compile(r"^(\s*)```(.*)$")
#: markers of a whole page (the others apply to the next block)
PAGE_MARKERS = ("skip-page", "requires-page")
BLOCK_MARKERS = ("skip", "requires", "import-only")
#: below this magnitude two numbers are round-off and compare equal
ROUND_OFF = 1e-9
#: relative differences below this are round-off (the digits of a full-precision number
#: beyond the tenth)
RELATIVE = 1e-10


@dataclass
class Block:
    lang: str
    text: str
    line: int
    markers: list[tuple[str, str]] = field(default_factory=list)
    heading_before: bool = False  # a heading between this block and the previous one
    prose_before: str = ""  # the text between the previous block and this one

    def shows_output(self) -> bool:
        """A text block that shows the previous block's output: right after it, or after
        prose ending with a colon ("... prints:"), no heading between."""
        prose = [ln for ln in self.prose_before.splitlines()
                 if ln.strip() and not ln.lstrip().startswith("<!--")]
        return self.lang == "text" and not self.heading_before and (
            not prose or prose[-1].rstrip().endswith(":"))

    def marker(self, kind: str) -> str | None:
        return next((reason for k, reason in self.markers if k == kind), None)


@dataclass
class Page:
    path: Path
    blocks: list[Block]
    markers: list[tuple[str, str]]  # page-level markers (PAGE_MARKERS)

    @property
    def name(self) -> str:
        return (self.path.relative_to(ROOT).as_posix() if ROOT in self.path.parents
                else self.path.name)


def parse(path: Path, runnable: bool = True) -> Page:
    """The fenced blocks of a page, each with the markers written since the block before
    (`runnable`: without the README's tutorial, which tests/test_readme_tutorial.py runs)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    if path == README and runnable:
        start = next((i for i, ln in enumerate(lines) if ln.startswith(README_TUTORIAL)), None)
        if start is not None:
            end = next((i for i in range(start + 1, len(lines))
                        if lines[i].startswith("## ")), len(lines))
            lines = lines[:start] + [""] * (end - start) + lines[end:]
    blocks: list[Block] = []
    pending: list[tuple[str, str]] = []
    page_markers: list[tuple[str, str]] = []
    heading = False
    prose: list[str] = []
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m is None:
            prose.append(lines[i])
            if lines[i].startswith("#"):
                heading = True
            if "<!--" in lines[i]:  # a marker, possibly over several lines
                chunk = [lines[i]]
                while "-->" not in chunk[-1] and i + 1 < len(lines):
                    i += 1
                    chunk.append(lines[i])
                for kind, reason in MARKER.findall("\n".join(chunk)):
                    target = page_markers if kind in PAGE_MARKERS else pending
                    target.append((kind, " ".join(reason.split())))
            i += 1
            continue
        indent, lang = m.group(1), m.group(2).strip()
        body = []
        start = i + 1
        i += 1
        while i < len(lines) and not re.match(rf"^{re.escape(indent)}```\s*$", lines[i]):
            body.append(lines[i][len(indent):] if lines[i].startswith(indent) else lines[i])
            i += 1
        blocks.append(Block(lang, "\n".join(body) + "\n", start, pending, heading,
                            "\n".join(prose)))
        pending, heading, prose = [], False, []
        i += 1
    return Page(path, blocks, page_markers)


def pages() -> list[Path]:
    """Every docs page and the README."""
    return [*sorted(DOCS.glob("*.md")), README]


# ---------------------------------------------------------------------------- comparing
def _unit(token: str) -> float | None:
    """One unit of the last digit shown in a number token; None for a whole number."""
    mant, _, exp = token.lower().partition("e")
    if "." not in mant and not exp:
        return None
    decimals = len(mant.split(".", 1)[1]) if "." in mant else 0
    return 10.0 ** (int(exp or 0) - decimals)


def _same_number(expected: str, actual: str) -> bool:
    e, a = float(expected), float(actual)
    if abs(e) < ROUND_OFF and abs(a) < ROUND_OFF:
        return True
    unit = _unit(expected)
    if unit is None:
        return e == a
    # one unit of the last digit shown; of a full-precision number (repr of a computed
    # float) the digits beyond the tenth are round-off
    return math.isclose(e, a, rel_tol=RELATIVE, abs_tol=unit * 1.0000001)


def _line_pattern(expected: str) -> tuple[re.Pattern, list[str | None]]:
    """A regex for one expected line and the number each capture group must equal (None:
    a duration, not compared)."""
    parts, numbers = [], []
    for k, piece in enumerate(expected.strip().split("...")):
        if k:
            parts.append(".*?")
        pos = 0
        for m in NUMBER.finditer(piece):
            parts.append(_text_pattern(piece[pos:m.start()]))
            parts.append(r"([-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?|[-+]?inf|nan)")
            duration = re.match(r" s\b", piece[m.end():]) is not None
            numbers.append(None if duration else m.group())
            pos = m.end()
        parts.append(_text_pattern(piece[pos:]))
    return re.compile(r"\s*" + "".join(parts) + r"\s*"), numbers


def _text_pattern(text: str) -> str:
    return r"\s+".join(re.escape(w) for w in re.split(r"\s+", text)) if text.strip() else (
        r"\s*" if text else "")


def line_matches(expected: str, actual: str) -> bool:
    """One output line against one expected line (the rules in the module docstring)."""
    pattern, numbers = _line_pattern(expected)
    m = pattern.fullmatch(actual)
    if m is None:
        return False
    return all(want is None or _same_number(want, got)
               for want, got in zip(numbers, m.groups(), strict=True))


def output_matches(expected: list[str], actual: list[str]) -> bool:
    """All lines, where an expected line ``...`` stands for any number of lines."""
    exp = _trim(expected)
    act = _trim(actual)
    memo: dict[tuple[int, int], bool] = {}

    def match(i: int, j: int) -> bool:
        if (i, j) in memo:
            return memo[i, j]
        if i == len(exp):
            ok = j == len(act)
        elif exp[i].strip() == "...":
            ok = any(match(i + 1, k) for k in range(j, len(act) + 1))
        else:
            ok = j < len(act) and line_matches(exp[i], act[j]) and match(i + 1, j + 1)
        memo[i, j] = ok
        return ok

    return match(0, 0)


def _trim(lines: list[str]) -> list[str]:
    out = [ln.rstrip() for ln in lines]
    while out and not out[-1]:
        out.pop()
    while out and not out[0]:
        out.pop(0)
    return out


# ---------------------------------------------------------------------------- running
def console_steps(text: str) -> list[tuple[str, list[str]]]:
    """``(command, expected output)`` of each ``$`` line (a trailing backslash continues
    the command on the next line)."""
    steps: list[tuple[str, list[str]]] = []
    cont = False
    for line in text.splitlines():
        if cont:
            steps[-1] = (steps[-1][0] + "\n" + line, steps[-1][1])
            cont = line.endswith("\\")
        elif line.startswith("$ "):
            steps.append((line[2:], []))
            cont = line.endswith("\\")
        elif steps:
            steps[-1][1].append(line)
    return steps


def environment(bin_dir: Path, server: str | None = None) -> dict[str, str]:
    """This checkout's ``kinecal``, ``python`` and ``python3`` first on the PATH; stdout
    unbuffered, so that stdout and stderr interleave as on a terminal. With `server` (the
    socket of tests/docs_server.py) ``kinecal`` is its client, else a fresh interpreter."""
    bin_dir.mkdir(parents=True, exist_ok=True)
    exe = bin_dir / "kinecal"
    if server is None:
        exe.write_text(f'#!/bin/sh\nexec "{sys.executable}" -c '
                       f'"from kinecal.cli import main; main()" "$@"\n', encoding="utf-8")
    else:
        spec = importlib.util.spec_from_file_location("docs_server", SERVER)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        exe.write_text(module.client_script(sys.executable, server), encoding="utf-8")
        python = bin_dir / "docs-python"  # the python blocks (not a `python` of the page)
        python.write_text(module.client_script(sys.executable, server, "python"),
                          encoding="utf-8")
        python.chmod(0o755)
    exe.chmod(0o755)
    for name in ("python", "python3"):  # a script, not a link: a link to a venv's python
        script = bin_dir / name         # is not that venv's (no site-packages)
        script.write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n', encoding="utf-8")
        script.chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
               PYTHONPATH=str(ROOT / "src"), COLUMNS="100", MPLBACKEND="Agg",
               PYTHONDONTWRITEBYTECODE="1", PYTHONUNBUFFERED="1")
    env.pop("KINECAL_DEBUG", None)
    return env


def _run(argv: list[str], cwd: Path, env: dict[str, str]) -> tuple[int, str]:
    proc = subprocess.run(argv, cwd=cwd, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=TIMEOUT, check=False)
    return proc.returncode, proc.stdout


def _missing_modules(reason: str) -> list[str]:
    names = reason.split()[0].split(",") if reason.split() else []
    return [n for n in names if importlib.util.find_spec(n) is None]


@dataclass
class PageRun:
    failures: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    commands: int = 0
    seconds: float = 0.0


def run_page(page: Page, folder: Path, env: dict[str, str]) -> PageRun:
    """Run a page's blocks in order in `folder`; stop at its first failure."""
    out = PageRun()
    t0 = time.perf_counter()
    status = 0
    blocks = page.blocks
    for k, block in enumerate(blocks):
        where = f"{page.name}:{block.line}"
        reason = block.marker("skip")
        needs = block.marker("requires")
        if block.lang not in RUN:
            continue
        if reason is not None:
            out.skipped.append(f"{where}: {reason}")
            continue
        if needs is not None and _missing_modules(needs):
            out.skipped.append(f"{where}: needs {', '.join(_missing_modules(needs))}: {needs}")
            continue
        nxt = blocks[k + 1] if k + 1 < len(blocks) else None
        shown = (nxt.text.splitlines() if nxt is not None and nxt.shows_output()
                 and block.lang != "console" else None)
        if block.lang == "console":
            for command, expected in console_steps(block.text):
                out.commands += 1
                code, text = _run(["bash", "-o", "pipefail", "-c",
                                   f"( exit {status} ); {command}"], folder, env)
                status = code
                problem = _check(code, text, expected, command)
                if problem:
                    out.failures.append(f"{where}: `$ {command}`: {problem}")
                    return _done(out, t0)
            continue
        if block.lang == "python":
            if block.marker("import-only") is not None:
                problem = _import_check(block.text)
                if problem:
                    out.failures.append(f"{where}: {problem}")
                    return _done(out, t0)
                continue
            script = folder / f".docs-block-{block.line}.py"
            script.write_text(block.text, encoding="utf-8")
            python = shutil.which("docs-python", path=env["PATH"]) or sys.executable
            code, text = _run([python, script.name], folder, env)
            script.unlink()
        else:
            out.commands += sum(1 for ln in block.text.splitlines()
                                if re.match(r"\s*kinecal ", ln))
            code, text = _run(["bash", "-e", "-o", "pipefail", "-c", block.text], folder, env)
        if code != 0:
            out.failures.append(f"{where}: {block.lang} block exited {code}:\n{text}")
            return _done(out, t0)
        if shown is not None and not output_matches(shown, text.splitlines()):
            out.failures.append(f"{where}: the {block.lang} block printed:\n{text}\n--- the page "
                                f"shows (line {nxt.line}):\n" + "\n".join(shown))
            return _done(out, t0)
    return _done(out, t0)


def _done(out: PageRun, t0: float) -> PageRun:
    out.seconds = time.perf_counter() - t0
    return out


def _check(code: int, text: str, expected: list[str], command: str) -> str | None:
    if not output_matches(expected, text.splitlines()):
        return "printed:\n" + text + "\n--- the page shows:\n" + "\n".join(_trim(expected))
    if command.rstrip().endswith("echo $?") or not command.startswith("kinecal "):
        return None  # the status shown, or another tool's (diff: 1 when files differ)
    want = 2 if any(ln.startswith("kinecal: error:") for ln in expected) else 0
    return None if code == want else f"exited {code}, expected {want}:\n{text}"


def _import_check(source: str) -> str | None:
    """A python block compiles and every module it imports exists."""
    try:
        tree = ast.parse(source)
    except SyntaxError as exc:
        return f"python block does not compile: {exc}"
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [(a.name, None) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names = [(node.module, a.name) for a in node.names]
        else:
            continue
        for module, attr in names:
            try:
                mod = __import__(module, fromlist=[attr] if attr else [])
            except ImportError as exc:
                return f"import {module}: {exc}"
            if attr and attr != "*" and not hasattr(mod, attr):
                try:
                    __import__(f"{module}.{attr}")
                except ImportError:
                    return f"from {module} import {attr}: no such name"
    return None


# ---------------------------------------------------------------------------- the tests
PAGE_NAMES = [p.relative_to(ROOT).as_posix() for p in pages()]


@pytest.fixture(scope="session")
def walkthroughs(request, tmp_path_factory) -> dict[str, PageRun]:
    """Run the selected pages, `WORKERS` at a time; their outcomes by page name."""
    selected = [item.callspec.params["name"] for item in request.session.items
                if getattr(item, "originalname", None) == "test_walkthrough_runs_as_written"]
    bin_dir = tmp_path_factory.mktemp("bin")
    env = environment(bin_dir)
    server = None
    if not os.environ.get("KINECAL_DOCS_PLAIN") and selected:
        server = _start_server(bin_dir / "kinecal.sock", env)
        env = environment(bin_dir, str(bin_dir / "kinecal.sock"))
    todo = []
    for name in selected:
        page = parse(ROOT / name)
        if not any(k == "skip-page" for k, _ in page.markers):
            todo.append(page)
    # the longest pages first, so that two workers finish together
    todo.sort(key=lambda p: -sum(b.text.count("kinecal ") for b in p.blocks if b.lang in RUN))

    def one(page: Page) -> tuple[str, PageRun]:
        needs = next((r for k, r in page.markers if k == "requires-page"), None)
        if needs is not None and _missing_modules(needs):
            return page.name, PageRun(skipped=[f"page: {needs}"])
        folder = tmp_path_factory.mktemp(page.path.stem)
        return page.name, run_page(page, folder, env)

    try:
        with ThreadPoolExecutor(WORKERS) as pool:
            return dict(pool.map(one, todo))
    finally:
        if server is not None:
            server.terminate()
            server.wait(timeout=30)


def _start_server(address: Path, env: dict[str, str]) -> subprocess.Popen:
    """tests/docs_server.py serving `address` (its start-up: about a second)."""
    log = address.with_suffix(".log")
    with open(log, "wb") as fh:
        proc = subprocess.Popen([sys.executable, str(SERVER), str(address)], env=env,
                                stdin=subprocess.DEVNULL, stdout=fh, stderr=fh)
    deadline = time.monotonic() + 120
    while not address.exists():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise RuntimeError("docs server did not start:\n" + log.read_text())
        time.sleep(0.05)
    return proc


@pytest.mark.parametrize("name", PAGE_NAMES)
def test_walkthrough_runs_as_written(name, walkthroughs):
    page = parse(ROOT / name)
    skip = next((r for k, r in page.markers if k == "skip-page"), None)
    if skip is not None:
        pytest.skip(f"{name}: {skip}")
    run = walkthroughs[name]
    if run.skipped and run.skipped[0].startswith("page:"):
        pytest.skip(f"{name}: {run.skipped[0]}")
    print(f"{name}: {run.commands} commands in {run.seconds:.1f} s")
    for s in run.skipped:  # reported, never silent
        print(f"not run: {s}")
    assert not run.failures, "\n".join(run.failures)


def test_every_block_says_what_it_is_and_every_marker_why():
    """No fence without a language (a command block would go unrun unseen), no ``$``
    prompt outside a console block, and every marker with a reason."""
    bad = []
    for path in pages():
        page = parse(path, runnable=False)
        inside = False
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if FENCE.match(line):
                inside = not inside
            elif not inside and re.match(r"( {4}|\t)(\$ )?kinecal ", line):
                bad.append(f"{page.name}:{n}: an indented command: fence it (```sh)")
        for b in page.blocks:
            where = f"{page.name}:{b.line}"
            if not b.lang:
                bad.append(f"{where}: a block without a language (sh, console, python, text, "
                           "yaml, ...)")
            if b.lang not in ("console", "markdown") and any(
                    ln.startswith("$ ") for ln in b.text.splitlines()):
                bad.append(f"{where}: `$ ` prompts belong in a console block")
            for kind, reason in b.markers:
                if kind not in BLOCK_MARKERS:
                    bad.append(f"{where}: unknown marker {kind!r}")
                elif len(reason.split()) < 3:
                    bad.append(f"{where}: marker {kind} without a reason")
        for kind, reason in page.markers:
            if kind not in PAGE_MARKERS:
                bad.append(f"{page.name}: unknown marker {kind!r}")
            elif len(reason.split()) < 3:
                bad.append(f"{page.name}: marker {kind} without a reason")
            for test in re.findall(r"tests/[\w/]+\.py", reason):  # run by another test
                if path.name not in (ROOT / test).read_text(encoding="utf-8"):
                    bad.append(f"{page.name}: {test} does not run this page")
    assert bad == []


def test_the_comparison_rules():
    """The rules of the module docstring, including the ones that must fail."""
    assert line_matches("mean 0.1036 mm", "mean 0.1037 mm")  # one unit of the last digit
    assert not line_matches("mean 0.1036 mm", "mean 0.1038 mm")
    assert not line_matches("5 iterations, 6 evaluations", "6 iterations, 7 evaluations")
    assert line_matches("condition number 5.76e+03", "condition number 5.77e+03")
    assert not line_matches("condition number 10.9", "condition number 8.28")
    assert line_matches("residual 2.54e-13 mm", "residual 9.1e-14 mm")  # round-off
    assert line_matches("0.680087954719216", "0.6800879547192039")
    assert not line_matches("0.680087954719216", "0.6800879548")
    assert not line_matches("residual 2.54e-06 mm", "residual 9.1e-07 mm")
    assert line_matches("0.0258 s", "1.7 s") and line_matches("x  -0.000000", "x   0.000000")
    assert not line_matches("mean 0.1036 mm", "mean 0.1036 m")
    assert line_matches("wrote ... files to ...", "wrote 12 files to /tmp/x/demo")
    assert output_matches(["a", "...", "d"], ["a", "b", "c", "d"])
    assert output_matches(["a", "...", "b"], ["a", "b"])
    assert not output_matches(["a", "b"], ["a", "b", "c"])
    page = Page(README, [], [])
    assert page.name == "README.md"
    steps = console_steps("$ kinecal a \\\n    --b 1\nout\n$ echo $?\n2\n")
    assert steps == [("kinecal a \\\n    --b 1", ["out"]), ("echo $?", ["2"])]


def test_a_page_that_goes_wrong_fails(tmp_path):
    """The runner itself: a shown output that differs, a failing block, an unexpected
    status and a skipped block are each reported (plain interpreters, cheap commands)."""
    page = tmp_path / "page.md"
    page.write_text(
        "# t\n\n```sh\nprintf 'a,b\\n1,2\\n' > f.csv\necho made\n```\n\nprints:\n\n"
        "```text\nmade\n```\n\n```console\n$ cat f.csv\na,b\n1,2\n$ kinecal --version\n"
        "kinecal ...\n```\n\n<!-- docs-test: skip it would fail, on purpose -->\n"
        "```sh\nfalse\n```\n\n```python\nprint(open('f.csv').read().split()[1])\n```\n"
        "```text\n1,2\n```\n", encoding="utf-8")
    env = environment(tmp_path / "bin")
    run = run_page(parse(page), tmp_path, env)
    assert run.failures == [] and run.skipped == [f"{parse(page).name}:23: it would fail, "
                                                  "on purpose"], run
    assert run.commands == 2
    for old, new in (("made\n```", "maid\n```"), ("1,2\n$", "1,3\n$"),
                     ("kinecal --version", "kinecal calibrate ur5 missing.csv"),
                     ("[1])", "[7])")):
        page.write_text(page.read_text(encoding="utf-8").replace(old, new, 1), "utf-8")
        assert run_page(parse(page), tmp_path, env).failures, old
        page.write_text(page.read_text(encoding="utf-8").replace(new, old, 1), "utf-8")

