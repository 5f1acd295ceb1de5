"""kinecal._files: stale temporary files of killed writes are swept; YAML alias bombs refused."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from kinecal import _temps
from kinecal._files import atomic_open, write_text_atomic
from kinecal._temps import STALE_TEMP_SECONDS, sweep_stale_temp_files
from kinecal._yaml import load_yaml, read_yaml_mapping
from kinecal.errors import InputError

SRC = str(Path(__file__).resolve().parents[2] / "src")


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def _temp_name(target: str, host: str, pid: int) -> str:
    return f".{target}.kinecal-{host}-{pid}.x1y2z3.tmp"


def test_killed_write_leaves_a_temp_file_that_the_next_write_removes(tmp_path):
    """SIGKILL in the middle of an atomic write leaves the hidden temporary file; the next
    write into the same folder (by any kinecal process) removes it."""
    code = (f"import sys, time; sys.path.insert(0, {SRC!r})\n"
            "from kinecal._files import atomic_open\n"
            f"with atomic_open({str(tmp_path / 'big.csv')!r}) as fh:\n"
            "    fh.write('x' * 1_000_000); fh.flush(); print('ready', flush=True)\n"
            "    time.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        proc.kill()
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].startswith(".big.csv.kinecal-")  # big.csv never made
    assert (tmp_path / left[0]).stat().st_size == 1_000_000
    _temps._SWEPT.discard(os.path.abspath(tmp_path))
    write_text_atomic(tmp_path / "other.json", "{}\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.json"]


def test_sweep_keeps_live_writers_foreign_files_and_fresh_files_of_other_hosts(tmp_path):
    host = _temps.host_tag()
    other = "0" * 8 if host != "0" * 8 else "1" * 8
    dead, alive = _dead_pid(), os.getppid()
    names = {
        "dead": _temp_name("a.csv", host, dead),
        "alive": _temp_name("b.csv", host, alive),
        "other-host-fresh": _temp_name("c.csv", other, dead),
        "other-host-old": _temp_name("d.csv", other, dead),
        "old-alive": _temp_name("e.csv", host, alive),
        "not-ours": ".f.csv.abc123.tmp",
        "data": "g.csv",
    }
    for name in names.values():
        (tmp_path / name).write_text("x", encoding="utf-8")
    old = time.time() - STALE_TEMP_SECONDS - 60
    for key in ("other-host-old", "old-alive", "not-ours", "data"):
        os.utime(tmp_path / names[key], (old, old))
    removed = {p.name for p in sweep_stale_temp_files(tmp_path)}
    assert removed == {names["dead"], names["other-host-old"], names["old-alive"]}
    assert {p.name for p in tmp_path.iterdir()} == {
        names["alive"], names["other-host-fresh"], names["not-ours"], names["data"]}


def test_failed_write_removes_its_temp_file_and_long_names_fit(tmp_path):
    target = tmp_path / ("n" * 250)
    with pytest.raises(RuntimeError), atomic_open(target) as fh:
        fh.write("partial")
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
    write_text_atomic(target, "whole\n")
    assert [p.name for p in tmp_path.iterdir()] == [target.name]


def test_symlinked_output_replaces_the_target_and_keeps_the_link(tmp_path):
    real = tmp_path / "real.json"
    real.write_text("old\n", encoding="utf-8")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    write_text_atomic(link, "new\n")
    assert link.is_symlink() and real.read_text(encoding="utf-8") == "new\n"


BOMB = "\n".join(
    ['a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    + [f"{chr(97 + i)}: &{chr(97 + i)} [" + ", ".join([f"*{chr(96 + i)}"] * 9) + "]"
       for i in range(1, 10)]) + "\n"


def test_billion_laughs_is_refused_before_it_is_built(tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(BOMB, encoding="utf-8")
    t0 = time.perf_counter()
    with pytest.raises(InputError, match="alias bomb") as exc:
        read_yaml_mapping(path)
    assert time.perf_counter() - t0 < 5.0  # composed, counted, refused: never expanded
    assert exc.value.file == str(path) and "4.41e+09 nodes" in exc.value.message


def test_recursive_alias_and_deep_nesting_are_input_errors():
    with pytest.raises(InputError, match="refers to itself"):
        load_yaml("a: &a [1, *a]\n")
    with pytest.raises(InputError, match="nested too deeply"):
        load_yaml("a: " + "[" * 3000 + "]" * 3000)
    with pytest.raises(InputError, match="not valid YAML"):
        load_yaml("\x1f")


def test_ordinary_anchors_and_merges_still_work():
    doc = load_yaml("defaults: &d {model: irb120, noise: 0.01}\n"
                    "jobs:\n  - {<<: *d, name: a, poses: 10}\n  - {<<: *d, name: b, poses: 20}\n")
    assert doc["jobs"][1] == {"model": "irb120", "noise": 0.01, "name": "b", "poses": 20}
    # a few thousand nodes of aliases are far below the cap
    wide = "x: &x [" + ", ".join(["1"] * 1000) + "]\ny: [" + ", ".join(["*x"] * 500) + "]\n"
    assert len(load_yaml(wide)["y"]) == 500


def test_devices_and_endless_streams_are_refused_not_read(tmp_path):
    """``/dev/zero`` as a model, jobs, JSON or CSV input would be read until the memory
    runs out: devices are refused by name, and a text input is read at most to its cap."""
    import threading

    from kinecal._files import read_text
    from kinecal.cli._common import resolve_data_path

    for reader in (read_text, lambda p: resolve_data_path(p, "DATA")):
        with pytest.raises(InputError, match="is a device"):
            reader("/dev/zero")
    fifo = tmp_path / "endless.json"
    os.mkfifo(fifo)
    def write() -> None:
        with contextlib.suppress(BrokenPipeError):
            fifo.write_bytes(b"[" * 5000)

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    with pytest.raises(InputError, match="too large"):
        read_text(fifo, max_bytes=1000)
    writer.join(5)
