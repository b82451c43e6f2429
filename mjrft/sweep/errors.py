"""The error a study raises for bad input: it names the file, key, path or value at fault."""

from __future__ import annotations


class StudyError(ValueError):
    """A study description (or a results folder it is run into) is invalid; the message names
    the offending file, key, parameter path or value and says what would be valid."""


def one_line(text: str) -> str:
    """`text` on one line (MuJoCo's compiler errors span several), so that every row of a
    results table is one line of the file."""
    return " | ".join(part.strip() for part in str(text).splitlines() if part.strip())
