"""The machinery of tests/test_docs_walkthroughs.py (its docstring has the rules): a docs
page parsed into fenced blocks with their markers, the comparison of printed output with the
output a page shows, and the run of a page's blocks in a scratch folder."""

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
from dataclasses import dataclass, field
from pathlib import Path

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


def missing_modules(reason: str) -> list[str]:
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
        if needs is not None and missing_modules(needs):
            out.skipped.append(f"{where}: needs {', '.join(missing_modules(needs))}: {needs}")
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


def start_server(address: Path, env: dict[str, str]) -> subprocess.Popen:
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
