"""The command lists of `kinecal --help` and `kinecal stewart --help` read well: click cuts
each command's first line at its first full stop, so an abbreviation there ("eq.", "e.g.")
would leave a torn phrase in the list."""

import re

import pytest

from kinecal.cli import main


@pytest.mark.parametrize("args", [["--help"], ["stewart", "--help"]])
def test_command_lists_have_no_torn_first_sentences(args, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    assert main(args) == 0
    out = capsys.readouterr().out
    listed = out.split("Commands:", 1)[1]
    rows = [line.strip() for line in listed.splitlines() if line.strip()]
    assert len(rows) >= 4
    for row in rows:
        assert not re.search(r"\b(eq|eqs|e\.g|i\.e|sec|cf|vs)\.(\.\.)?$", row), row
        assert row.count("(") == row.count(")") or row.endswith("..."), row
