"""The errors a sweep raises: bad input (``StudyError``, naming the file, key, path or value at
fault), a results folder another sweep holds (``FolderLocked``), and a sweep stopped by a
failure outside its runs (``SweepStopped``: a full disk, an unwritable folder)."""

from __future__ import annotations


class StudyError(ValueError):
    """A study description (or a results folder it is run into) is invalid; the message names
    the offending file, key, parameter path or value and says what would be valid."""


class FolderLocked(StudyError):
    """The results folder is being written by another sweep; the message names it (pid, host,
    start time)."""


class SweepStopped(RuntimeError):
    """The sweep stopped because something outside its runs failed (the disk is full, the
    results folder cannot be written): every row written before is whole in the table, no run
    was recorded as failed for it, and resuming continues (the message says what failed)."""


def one_line(text: str) -> str:
    """`text` on one line (MuJoCo's compiler errors span several), so that every row of a
    results table is one line of the file."""
    return " | ".join(part.strip() for part in str(text).splitlines() if part.strip())
