"""``kinecal bench`` runs the package's own benchmark scripts, never the working directory's."""

from __future__ import annotations

from pathlib import Path

import kinecal
from kinecal.cli import main
from kinecal.cli.bench import find_benchmarks

CHECKOUT = Path(kinecal.__file__).resolve().parents[2]


def test_a_bench_script_in_the_working_directory_is_never_run(tmp_path, monkeypatch, capsys):
    marker = tmp_path / "PWNED"
    evil = tmp_path / "benchmarks"
    evil.mkdir()
    for name in ("bench_evil.py", "bench_fk.py"):  # a new name and a shadowing one
        (evil / name).write_text(f"open({str(marker)!r}, 'w').write('ran')\n",
                                 encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert find_benchmarks() == CHECKOUT / "benchmarks"
    code = main(["bench", "--only", "evil"])
    err = capsys.readouterr().err
    assert code == 2 and "unknown benchmark evil" in err and err.count("\n") == 1
    assert not marker.exists()


def test_an_installed_package_without_a_checkout_is_told_so(tmp_path, monkeypatch, capsys):
    """A wheel install (site-packages/kinecal) has no benchmarks: exit 2, one line."""
    fake = tmp_path / "site-packages" / "kinecal"
    fake.mkdir(parents=True)
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks" / "bench_x.py").write_text("raise SystemExit(3)\n")
    monkeypatch.setattr(kinecal, "__file__", str(fake / "__init__.py"))
    monkeypatch.chdir(tmp_path)
    assert main(["bench"]) == 2
    err = capsys.readouterr().err
    assert "not from a source checkout" in err and err.count("\n") == 1
