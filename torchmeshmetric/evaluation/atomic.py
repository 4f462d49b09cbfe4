"""Atomic file writes: a temporary file in the destination folder, then :func:`os.replace`.

A reader (or a crash) never sees a half-written report: either the old file (or none) or the complete new one.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

__all__ = ["atomic_write", "atomic_write_with"]


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_with(
    path: str | os.PathLike[str], write: Callable[[BinaryIO], object], *, overwrite: bool = False
) -> Path:
    """Create ``path`` atomically from ``write(binary_file)``.

    Args:
        path: destination file; its folder must exist.
        write: writes the content to the open binary temporary file.
        overwrite: replace an existing file (default ``False``: never overwrite a user's file unasked).

    Returns:
        The destination path.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        FileNotFoundError, PermissionError, IsADirectoryError: the destination folder is missing or unwritable.
    """
    dest = Path(path)
    if dest.is_dir():
        raise IsADirectoryError(f"path: {str(dest)!r} is a directory, expected a file path")
    if dest.exists() and not overwrite:
        raise FileExistsError(f"path: {str(dest)!r} already exists (pass overwrite=True / --overwrite to replace it)")
    folder = dest.parent if str(dest.parent) else Path(".")
    if not folder.is_dir():
        raise FileNotFoundError(f"path: folder {str(folder)!r} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp", dir=folder)
    try:
        os.chmod(tmp, dest.stat().st_mode & 0o777 if dest.exists() else 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, dest)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return dest


def atomic_write(path: str | os.PathLike[str], data: str | bytes, *, overwrite: bool = False) -> Path:
    """Write text (UTF-8) or bytes to ``path`` atomically (see :func:`atomic_write_with`).

    Example:
        >>> import tempfile, os
        >>> d = tempfile.mkdtemp()
        >>> p = atomic_write(os.path.join(d, "a.txt"), "hello")
        >>> p.read_text(), sorted(os.listdir(d))
        ('hello', ['a.txt'])
    """
    payload = data.encode("utf-8") if isinstance(data, str) else data
    return atomic_write_with(path, lambda fh: fh.write(payload), overwrite=overwrite)
