"""Where a command's outputs go: the checks made before any work, and the writing of them as one set.

Light on purpose (no torch, no evaluation system): every command imports it, the fast ones (``ctc``, ``mpeg``,
``sample``) included.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from torchmeshmetric._atomic import atomic_file_set, blocking_file

__all__ = ["CLIError", "check_folder", "check_writable", "make_folder", "output_set"]


class CLIError(Exception):
    """An error reported to the user as one line (exit code 1)."""


def check_folder(folder: Path, what: str, *, may_create: bool = False) -> None:
    """An output folder: existing (or, with ``may_create``, missing), never a file nor below a file."""
    if not folder.is_dir():
        blocker = blocking_file(folder)
        if blocker is not None:
            raise CLIError(f"{what} {str(folder)!r}: {str(blocker)!r} is a file, not a folder")
        if not may_create:
            raise CLIError(f"{what} {str(folder)!r} does not exist")


def make_folder(folder: Path, what: str, files: Any) -> None:
    """Create an output folder inside a file set (removed again when the run fails), naming a file in the way."""
    try:
        files.mkdir(folder)
    except (FileExistsError, NotADirectoryError) as exc:  # a file appeared in the way since the check
        check_folder(folder, what)
        raise CLIError(f"{what} {str(folder)!r}: cannot create it ({exc.strerror})") from exc
    except OSError as exc:
        raise CLIError(f"{what} {str(folder)!r}: cannot create it ({exc.strerror})") from exc


@contextlib.contextmanager
def output_set(what: str) -> Iterator[Any]:
    """Write this run's outputs as one set (all or none); a write error becomes one line saying nothing was kept."""
    try:
        with atomic_file_set() as files:
            yield files
    except OSError as exc:
        reason = exc.strerror or str(exc)
        where = f" ({exc.filename})" if exc.filename else ""
        raise CLIError(f"could not write {what}: {reason}{where}; none of its files was written") from exc


def check_writable(paths: Sequence[Path], overwrite: bool) -> None:
    """Fail before any computation when an output cannot be written."""
    for path in paths:
        folder = path.parent if str(path.parent) else Path(".")
        check_folder(folder, "output folder")
        if not os.access(folder, os.W_OK):
            raise CLIError(f"output folder {str(folder)!r} is not writable")
        if path.is_dir():
            raise CLIError(f"output {str(path)!r} is a directory, expected a file")
        if path.exists() and not overwrite:
            raise CLIError(f"output {str(path)!r} already exists (pass --overwrite to replace it)")
