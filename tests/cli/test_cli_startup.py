"""A fast command line: ``kinecal --help`` imports no heavy library, and the kinematics
modules import each other in one direction only."""

import os
import subprocess
import sys

HEAVY = ("scipy", "matplotlib", "pydantic", "rich", "yaml", "pandas")


def _modules_after(code: str) -> set[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    show = "import sys\nprint(' '.join(sys.modules), file=sys.stderr)"
    out = subprocess.run([sys.executable, "-c", f"{code}\n{show}"], capture_output=True,
                         text=True, env=env, check=True)
    return set(out.stderr.split())


def test_help_imports_no_heavy_library():
    loaded = _modules_after("import io, contextlib\nfrom kinecal.cli import main\n"
                            "with contextlib.redirect_stdout(io.StringIO()):\n"
                            "    assert main(['--help']) == 0")
    assert "kinecal.cli.serial" in loaded  # every command was registered
    heavy = sorted(m for m in loaded if m.split(".")[0] in HEAVY)
    assert not heavy, heavy


def test_stewart_solvers_do_not_import_the_platform_class():
    """stewart.py calls stewart_fk and stewart_modes, never the other way round."""
    loaded = _modules_after("import kinecal.kinematics.stewart_modes")
    assert "kinecal.kinematics.stewart_fk" in loaded
    assert "kinecal.kinematics.stewart" not in loaded
