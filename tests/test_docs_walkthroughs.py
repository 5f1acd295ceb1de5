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

import importlib.util
import os
import re
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest


def _load(name: str):
    """A helper module beside this file (tests/ is not a package)."""
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


runner = _load("docs_runner")

# ---------------------------------------------------------------------------- the tests
#: the pages run here; a page marked ``skip-page`` is run by the test its marker names
#: (checked by `test_every_block_says_what_it_is_and_every_marker_why`)
PAGE_NAMES = [p.relative_to(runner.ROOT).as_posix() for p in runner.pages()
              if not any(k == "skip-page" for k, _ in runner.parse(p).markers)]


@pytest.fixture(scope="session")
def walkthroughs(request, tmp_path_factory) -> dict[str, runner.PageRun]:
    """Run the selected pages, `WORKERS` at a time; their outcomes by page name."""
    selected = [item.callspec.params["name"] for item in request.session.items
                if getattr(item, "originalname", None) == "test_walkthrough_runs_as_written"]
    bin_dir = tmp_path_factory.mktemp("bin")
    env = runner.environment(bin_dir)
    server = None
    if not os.environ.get("KINECAL_DOCS_PLAIN") and selected:
        server = runner.start_server(bin_dir / "kinecal.sock", env)
        env = runner.environment(bin_dir, str(bin_dir / "kinecal.sock"))
    todo = []
    for name in selected:
        page = runner.parse(runner.ROOT / name)
        if not any(k == "skip-page" for k, _ in page.markers):
            todo.append(page)
    # the longest pages first, so that two workers finish together
    todo.sort(key=lambda p: -sum(b.text.count("kinecal ") for b in p.blocks
                                 if b.lang in runner.RUN))

    def one(page: runner.Page) -> tuple[str, runner.PageRun]:
        needs = next((r for k, r in page.markers if k == "requires-page"), None)
        if needs is not None and runner.missing_modules(needs):
            return page.name, runner.PageRun(skipped=[f"page: {needs}"])
        folder = tmp_path_factory.mktemp(page.path.stem)
        return page.name, runner.run_page(page, folder, env)

    try:
        with ThreadPoolExecutor(runner.WORKERS) as pool:
            return dict(pool.map(one, todo))
    finally:
        if server is not None:
            server.terminate()
            server.wait(timeout=30)


@pytest.mark.parametrize("name", PAGE_NAMES)
def test_walkthrough_runs_as_written(name, walkthroughs):
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
    for path in runner.pages():
        page = runner.parse(path, runnable=False)
        inside = False
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if runner.FENCE.match(line):
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
                if kind not in runner.BLOCK_MARKERS:
                    bad.append(f"{where}: unknown marker {kind!r}")
                elif len(reason.split()) < 3:
                    bad.append(f"{where}: marker {kind} without a reason")
        for kind, reason in page.markers:
            if kind not in runner.PAGE_MARKERS:
                bad.append(f"{page.name}: unknown marker {kind!r}")
            elif len(reason.split()) < 3:
                bad.append(f"{page.name}: marker {kind} without a reason")
            if kind == "skip-page" and not re.search(r"tests/[\w/]+\.py", reason):
                bad.append(f"{page.name}: skip-page must name the test that runs the page")
            for test in re.findall(r"tests/[\w/]+\.py", reason):  # run by another test
                if path.name not in (runner.ROOT / test).read_text(encoding="utf-8"):
                    bad.append(f"{page.name}: {test} does not run this page")
    assert bad == []


def test_the_comparison_rules():
    """The rules of the module docstring, including the ones that must fail."""
    assert runner.line_matches("mean 0.1036 mm", "mean 0.1037 mm")  # one unit of the last digit
    assert not runner.line_matches("mean 0.1036 mm", "mean 0.1038 mm")
    assert not runner.line_matches("5 iterations, 6 evaluations", "6 iterations, 7 evaluations")
    assert runner.line_matches("condition number 5.76e+03", "condition number 5.77e+03")
    assert not runner.line_matches("condition number 10.9", "condition number 8.28")
    assert runner.line_matches("residual 2.54e-13 mm", "residual 9.1e-14 mm")  # round-off
    assert runner.line_matches("0.680087954719216", "0.6800879547192039")
    assert not runner.line_matches("0.680087954719216", "0.6800879548")
    assert not runner.line_matches("residual 2.54e-06 mm", "residual 9.1e-07 mm")
    assert runner.line_matches("0.0258 s", "1.7 s")
    assert runner.line_matches("x  -0.000000", "x   0.000000")
    assert not runner.line_matches("mean 0.1036 mm", "mean 0.1036 m")
    assert runner.line_matches("wrote ... files to ...", "wrote 12 files to /tmp/x/demo")
    assert runner.output_matches(["a", "...", "d"], ["a", "b", "c", "d"])
    assert runner.output_matches(["a", "...", "b"], ["a", "b"])
    assert not runner.output_matches(["a", "b"], ["a", "b", "c"])
    page = runner.Page(runner.README, [], [])
    assert page.name == "README.md"
    steps = runner.console_steps("$ kinecal a \\\n    --b 1\nout\n$ echo $?\n2\n")
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
    env = runner.environment(tmp_path / "bin")
    run = runner.run_page(runner.parse(page), tmp_path, env)
    assert run.failures == [] and run.skipped == [f"{runner.parse(page).name}:23: it would fail, "
                                                  "on purpose"], run
    assert run.commands == 2
    for old, new in (("made\n```", "maid\n```"), ("1,2\n$", "1,3\n$"),
                     ("kinecal --version", "kinecal calibrate ur5 missing.csv"),
                     ("[1])", "[7])")):
        page.write_text(page.read_text(encoding="utf-8").replace(old, new, 1), "utf-8")
        assert runner.run_page(runner.parse(page), tmp_path, env).failures, old
        page.write_text(page.read_text(encoding="utf-8").replace(new, old, 1), "utf-8")

