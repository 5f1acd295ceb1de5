"""A fast command line: ``kinecal --help`` imports no heavy library, and the kinematics
modules import each other in one direction only."""

import os
import subprocess
import sys

import numpy as np

HEAVY = ("scipy", "matplotlib", "pydantic", "rich", "yaml", "pandas", "sqlalchemy", "alembic",
         "psycopg")


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


#: imported on first use only: a command that never solves with them skips them (each
#: costs 0.1-0.3 s, more than a one-pose fk or a hand-eye bundle adjustment)
LATE_SCIPY = ("scipy.optimize", "scipy.special", "scipy.spatial", "scipy.sparse",
              "scipy.linalg")


def test_one_pose_fk_loads_no_solver_or_distribution(tmp_path):
    """``kinecal fk`` of one pose (scripts call it per target): no scipy.optimize (its
    import costs more than the command's work) nor scipy.special."""
    q = tmp_path / "q.csv"
    q.write_text("q1,q2,q3,q4,q5,q6\n0,10,20,30,40,50\n")
    loaded = _modules_after("import io, contextlib\nfrom kinecal.cli import main\n"
                            "with contextlib.redirect_stdout(io.StringIO()):\n"
                            f"    assert main(['fk', 'ur5', {str(q)!r}]) == 0")
    assert "kinecal.kinematics.serial.model" in loaded
    assert not loaded & set(LATE_SCIPY), sorted(loaded & set(LATE_SCIPY))


def test_handeye_images_loads_no_solver_or_distribution(tmp_path):
    """A clean hand-eye recording runs its bundle adjustment on kinecal's LM core
    (`kinecal.optimize.lm`), never building a scipy OptimizeResult, and judges no outlier
    station with a chi-square quantile (the robust bounds flag none): the command then
    starts like a plain OpenCV script plus kinecal's own modules."""
    from kinecal.vision.boards import parse_board
    from kinecal.vision.render import ImageConditions, render_handeye_scene, write_scene

    K = [[700.0, 0.0, 239.5], [0.0, 700.0, 179.5], [0.0, 0.0, 1.0]]
    board = parse_board("chessboard:9x6:20")
    sc = render_handeye_scene(board, np.array(K), np.zeros(5), (480, 360), 6,
                              conditions=ImageConditions(blur=0.7, noise=2.0), seed=5)
    folder = write_scene(sc, tmp_path / "scene")
    argv = ["handeye-images", str(folder / "images"), str(folder / "robot_poses.csv"),
            "--board", "chessboard:9x6:20", "--intrinsics", str(folder / "camera.yaml"),
            "--out", str(tmp_path / "x.json"), "--quiet"]
    loaded = _modules_after("import io, contextlib\nfrom kinecal.cli import main\n"
                            "with contextlib.redirect_stdout(io.StringIO()):\n"
                            f"    assert main({argv!r}) == 0")
    assert "kinecal.calibration.handeye.images" in loaded and (tmp_path / "x.json").exists()
    assert not loaded & set(LATE_SCIPY), sorted(loaded & set(LATE_SCIPY))
    # plain option values (kinecal.cli._coercion) and plain PNG files
    # (kinecal.vision.image_files) need neither pydantic nor Pillow
    late = sorted(m for m in loaded if m.split(".")[0] in ("pydantic", "PIL"))
    assert not late, late


def test_one_pose_fk_loads_no_solver():
    """``kinecal fk`` of one pose: no metaheuristic, no identifiability, no result reader
    (each a few to tens of ms of the command's start-up)."""
    loaded = _modules_after("import io, contextlib, tempfile, pathlib\n"
                            "from kinecal.cli import main\n"
                            "d = pathlib.Path(tempfile.mkdtemp())\n"
                            "(d / 'q.csv').write_text('q1,q2,q3,q4,q5,q6\\n0,10,20,30,40,50\\n')\n"
                            "with contextlib.redirect_stdout(io.StringIO()):\n"
                            "    assert main(['fk', 'ur5', str(d / 'q.csv')]) == 0")
    assert "kinecal.cli._fk_run" in loaded  # run without typer (kinecal.cli._direct)
    for module in ("kinecal.optimize.search", "kinecal.optimize.pso",
                   "kinecal.calibration.identifiability", "kinecal.io.result_values", "scipy"):
        assert module not in loaded, module


def test_optimize_submodules_load_no_metaheuristic():
    loaded = _modules_after("import kinecal.optimize.factor, kinecal.optimize.lm\n"
                            "from kinecal.optimize import METHODS")
    assert not {m for m in loaded if m.startswith("kinecal.optimize.")} - {
        "kinecal.optimize.factor", "kinecal.optimize.lm"}
    loaded = _modules_after("from kinecal.optimize import METHODS, _REGISTRY\n"
                            "assert METHODS == tuple(_REGISTRY)")
    assert "kinecal.optimize.search" in loaded


def test_one_pose_fk_loads_no_pydantic(tmp_path):
    """``kinecal fk`` of a bundled model: its values converted and its model file checked
    without pydantic (`kinecal.cli._direct`, `kinecal.io.model_plain`): importing it
    costs more than the command's work."""
    q = tmp_path / "q.csv"
    q.write_text("q1,q2,q3,q4,q5,q6\n0,10,20,30,40,50\n")
    loaded = _modules_after("import io, contextlib\nfrom kinecal.cli import main\n"
                            "with contextlib.redirect_stdout(io.StringIO()):\n"
                            f"    assert main(['fk', 'ur5', {str(q)!r}, '--angle-unit', "
                            "'deg']) == 0")
    assert "kinecal.kinematics.serial.model" in loaded
    assert not {m for m in loaded if m.split(".")[0] == "pydantic"}


def test_calibrate_loads_no_scipy_optimize():
    """The LM path of ``kinecal calibrate`` carries a `FitResult`, not scipy's
    OptimizeResult: no scipy.optimize import (0.13-0.17 s, a quarter of the command)."""
    loaded = _modules_after("import io, contextlib\nfrom kinecal.cli import main\n"
                            "with contextlib.redirect_stdout(io.StringIO()):\n"
                            "    assert main(['calibrate', 'ur5', 'ur5-laser-tracker:grid', "
                            "'--validate', 'ur5-laser-tracker:random']) == 0")
    assert "kinecal.calibration.serial.solve" in loaded
    assert "scipy.optimize" not in loaded
    assert not {m for m in loaded if m.split(".")[0] == "pydantic"}
