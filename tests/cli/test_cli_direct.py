"""Commands run without typer (`kinecal.cli._direct`): the table matches the typer
commands parameter for parameter, and every argument list the direct parser takes gets
exactly the keyword arguments typer would pass (values and types); the others go to typer."""

import io
import itertools
import subprocess
import sys
from contextlib import redirect_stdout

import numpy as np
import pytest

import kinecal.cli as cli
from kinecal.cli._direct import DIRECT, parse


def _typer_command(words):
    import typer.main

    cli._load_commands(list(words))
    group = typer.main.get_command(cli.app)
    ctx = group.make_context("kinecal", list(words))
    cmd = group
    for w in words:
        cmd = cmd.get_command(ctx, w)
    return cmd


def _typer_params(words, args):
    """typer's keyword arguments for ``kinecal WORDS ARGS`` (None: typer refuses them)."""
    from kinecal.cli import _types

    cmd = _typer_command(words)
    try:
        return cmd.make_context(" ".join(words), list(args)).params
    except (*_types("ClickException"), *_types("Exit")):
        return None


@pytest.mark.parametrize("words", list(DIRECT))
def test_table_matches_the_typer_command(words):
    d = DIRECT[words]
    cmd = _typer_command(words)
    args = [p for p in cmd.params if p.param_type_name == "argument"]
    assert tuple(p.name for p in args) == d.arguments
    assert all(p.required and p.nargs == 1 for p in args)
    opts = {p.name: p for p in cmd.params if p.param_type_name == "option"}
    covered = set()
    for table, kind in ((d.options, "value"), (d.repeated, "multiple"), (d.flags, "flag")):
        for flag, name in table.items():
            p = opts[name]
            assert p.opts == [flag] and not p.secondary_opts and not p.envvar, name
            assert p.callback is None and not p.is_eager and not p.prompt, name
            assert p.is_flag == (kind == "flag") and p.multiple == (kind == "multiple"), name
            assert p.default == d.defaults.get(name, False if kind == "flag" else None), name
            covered.add(name)
    assert set(opts) == covered | set(d.defaults)  # every option parsed or left to typer
    for name, value in d.defaults.items():
        assert opts[name].default == value


def _corpus(words, rng, n=1500):
    d = DIRECT[words]
    values = ["ur5", "q.csv", "x", "deg", "rad", "a=b", "-1", "", "--pose", "-", "tool0",
              "ur5:grid", "é", "a b", "newton", "pso", "liu2008-cmm", "3"]
    tokens = [*d.flags, *d.options, *d.repeated, "--help", "--", "-q", "--bogus",
              "--params", "--pose=1", "--version", "--seed"]
    out = []
    for _ in range(n):
        k = rng.integers(0, 7)
        args = []
        for _ in range(k):
            if rng.random() < 0.5:
                args.append(values[rng.integers(len(values))])
            else:
                t = tokens[rng.integers(len(tokens))]
                if t in d.options or t in d.repeated:
                    v = values[rng.integers(len(values))]
                    args.extend([f"{t}={v}"] if rng.random() < 0.3 else [t, v])
                else:
                    args.append(t)
        out.append(args)
    # plain lists the parser must take
    for extra in itertools.chain.from_iterable(itertools.combinations(
            [[f] for f in d.flags] + [[o, "v"] for o in d.options] +
            [[r, "a", r, "b"] for r in d.repeated], k) for k in range(3)):
        out.append(["ur5", *itertools.chain.from_iterable(extra), "q.csv"])
    return out


@pytest.mark.parametrize("words", list(DIRECT))
def test_direct_values_are_typers(words):
    rng = np.random.default_rng(11)
    taken = 0
    for args in _corpus(words, rng):
        direct = parse([*words, *args])
        if direct is None:
            continue
        taken += 1
        theirs = _typer_params(words, args)
        assert theirs is not None, args  # typer takes what the direct parser takes
        mine = direct[1]
        assert mine == theirs, (args, mine, theirs)
        assert {k: type(v) for k, v in mine.items()} == {k: type(v) for k, v in
                                                         theirs.items()}, args
    assert taken > 60


def test_help_and_odd_arguments_go_to_typer():
    for args in (["fk", "--help"], ["fk", "ur5"], ["fk", "ur5", "q.csv", "--", "x"],
                 ["fk", "ur5", "q.csv", "--params", "r.json"], ["fk", "-q", "ur5", "q.csv"],
                 ["fk", "ur5", "q.csv", "--angle-unit"], ["fk", "ur5", "q.csv", "--pose=1"],
                 ["--version"], ["fk", "ur5", "q.csv", "--tip", "a", "--tip", "b"]):
        assert parse(args) is None, args


def test_direct_fk_prints_what_typer_prints(tmp_path):
    """The same output and errors through both paths (`_run` with and without `direct`)."""
    from kinecal.io.geometry import load_geometry

    q = tmp_path / "q.csv"
    q.write_text("q1,q2,q3,q4,q5,q6\n0,10,20,30,40,50\n1,2,3,4,5,6\n")
    geom = load_geometry("liu2008-cmm")
    legs = geom.inverse(geom.random_poses(300, rng=1))
    good, bad = tmp_path / "legs.csv", tmp_path / "bad.csv"
    good.write_text("l1,l2,l3,l4,l5,l6\n" + "".join(",".join(map(repr, r)) + "\n"
                                                    for r in legs.tolist()))
    bad.write_text("l1,l2,l3,l4,l5,l6\n0.8,0.8,0.8,0.8,0.8,x\n")
    for args in (["fk", "ur5", str(q), "--pose"], ["fk", "irb120", str(q)],
                 ["fk", "ur5", str(tmp_path / "missing.csv")], ["fk", "nope", str(q)],
                 ["fk", "ur5", str(q), "--angle-unit", "grad"],
                 ["stewart", "fk", "liu2008-cmm", str(good)],
                 ["stewart", "fk", "liu2008-cmm", str(good), "--json", "--strict"],
                 ["stewart", "fk", "liu2008-cmm", str(bad)],
                 ["stewart", "fk", "liu2008-cmm", str(good), "--method", "bogus"]):
        outs = []
        for direct in (parse(args), None):
            env_code = ("import sys, kinecal.cli as c, kinecal.cli._direct\n"
                        f"args = {args!r}\n"
                        f"d = c._direct.parse(args) if {direct is not None} else None\n"
                        "c._load_commands(args) if d is None else None\n"
                        "try:\n    code = c._run(args, d)\n"
                        "except Exception as e:\n"
                        "    print('EXC', type(e).__name__, e, file=sys.stderr); code = -1\n"
                        "print('CODE', code, file=sys.stderr)\n")
            r = subprocess.run([sys.executable, "-c", env_code], capture_output=True,
                               text=True, check=False)
            timed = '"elapsed"'  # the solver's seconds differ between runs
            outs.append(([ln for ln in r.stdout.splitlines() if timed not in ln], r.stderr))
        assert outs[0] == outs[1], (args, outs)


def test_main_runs_fk_without_typer(tmp_path):
    q = tmp_path / "q.csv"
    q.write_text("q1,q2,q3,q4,q5,q6\n0,10,20,30,40,50\n")
    code = ("import io, sys, contextlib\nfrom kinecal.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    assert main(['fk', 'ur5', {str(q)!r}, '--pose']) == 0\n"
            "print(' '.join(sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       check=True)
    loaded = set(r.stdout.split())
    assert "kinecal.cli._fk_run" in loaded
    assert not {m for m in loaded if m.split(".")[0] in ("typer", "click", "pydantic")}
    with redirect_stdout(io.StringIO()) as out:
        assert cli.main(["fk", "ur5", str(q)]) == 0
    assert out.getvalue().splitlines()[0] == "x,y,z"
