"""Exceptions shared by the whole package.

`InputError` is the single error type for user mistakes (bad files, bad options,
bad arrays). The command line turns it into one line on stderr and exit status 2.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["InputError"]


class InputError(ValueError):
    """A user input (file, row, option or array) is not what kinecal expects.

    Parameters
    ----------
    message : str
        What was wrong and what was expected.
    file : str or Path, optional
        The file the input came from.
    row : int, optional
        The 1-based data row (header excluded) or station index where it was found.
    option : str, optional
        The option or argument name (for command-line or keyword arguments).
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        row: int | None = None,
        option: str | None = None,
    ) -> None:
        self.message = message
        self.file = None if file is None else str(file)
        self.row = row
        self.option = option
        super().__init__(self.one_line())

    def one_line(self) -> str:
        """Return the error as one line: ``file, row N: message`` or ``option X: message``."""
        where = []
        if self.file is not None:
            where.append(self.file)
        if self.row is not None:
            where.append(f"row {self.row}")
        if self.option is not None:
            where.append(f"option {self.option}")
        text = " ".join(self.message.split())
        return f"{', '.join(where)}: {text}" if where else text
