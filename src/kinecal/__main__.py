"""``python -m kinecal``: the command line (like the ``kinecal`` console script)."""

from kinecal.cli import main

main()
