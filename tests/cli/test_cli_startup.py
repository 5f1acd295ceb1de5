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
    assert {"kinecal.cli.fk", "kinecal.cli.calibrate"} <= loaded  # every command registered
    heavy = sorted(m for m in loaded if m.split(".")[0] in HEAVY)
    assert not heavy, heavy


def test_stewart_solvers_do_not_import_the_platform_class():
    """platform.py calls forward, pso, poses and modes, never the other way round."""
    loaded = _modules_after("import kinecal.kinematics.stewart.modes\n"
                            "import kinecal.kinematics.stewart.pso\n"
                            "import kinecal.kinematics.stewart.poses")
    assert "kinecal.kinematics.stewart.forward" in loaded
    assert "kinecal.kinematics.stewart.platform" not in loaded


def test_command_table_names_the_module_of_every_command():
    """``kinecal CMD`` imports only CMD's module (kinecal.cli._COMMANDS): every registered
    command must be in that table, with the module that registers it."""
    import kinecal.cli as cli

    cli._load_commands()
    found = {c.name or c.callback.__name__.replace("_", "-"): c.callback.__module__
             for c in cli.app.registered_commands}
    found.update({g.name: g.typer_instance.registered_commands[0].callback.__module__
                  for g in cli.app.registered_groups})
    found = {k: v for k, v in found.items() if v.startswith("kinecal.")}  # not test commands
    assert found == cli._COMMANDS, "update kinecal.cli._COMMANDS to the registered commands"
    assert set(found.values()) <= set(cli._COMMAND_MODULES)


def test_one_command_loads_its_module_alone():
    loaded = _modules_after("import io, contextlib\nfrom kinecal.cli import main\n"
                            "with contextlib.redirect_stdout(io.StringIO()):\n"
                            "    assert main(['stewart', '--help']) == 0")
    assert "kinecal.cli.stewart" in loaded
    assert "kinecal.cli.calibrate" not in loaded and "kinecal.cli.handeye" not in loaded
    # a module with one command: still a subcommand taking its own arguments (typer would
    # make a lone command the whole program without the app's callback)
    loaded = _modules_after("import io, contextlib\nfrom kinecal.cli import main\n"
                            "with contextlib.redirect_stderr(io.StringIO()) as err:\n"
                            "    assert main(['reproduce', 'no-such-paper']) == 2\n"
                            "assert 'no-such-paper' in err.getvalue(), err.getvalue()")
    assert "kinecal.cli.reproduce" in loaded and "kinecal.cli.fk" not in loaded
