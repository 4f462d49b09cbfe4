"""Atomic file writes: one file (temporary file in the destination folder, then :func:`os.replace`) or a set of files.

A reader (or a crash) never sees a half-written file: either the old file (or none) or the complete new one.
:func:`atomic_file_set` extends that to several files: every file written through :func:`atomic_write` /
:func:`atomic_write_with` inside ``with atomic_file_set():`` is staged, and all of them appear together when the
block ends without an error; on an error (a full disk while writing the third file, an exception of the caller),
none appears, files that existed before keep their content, and folders the set created are removed again.

Every file gets the permissions a plain ``open(path, "w")`` would give it (``0o666`` minus the umask), or keeps
those of the file it replaces.

A destination that is a symbolic link counts as an existing file, dangling or not (refused without ``overwrite``).
With ``overwrite`` the file the link points to is replaced and the link is kept, as ``open(link, "w")`` would do
(a dangling link: its target is created when the target's folder exists). The temporary and backup files are hidden
siblings of that file, ``.NAME.RANDOM.tmp`` / ``.NAME.RANDOM.bak`` with ``NAME`` shortened so that they stay within
the folder's file-name limit (255 bytes) even for the longest legal output name.
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import os
import secrets
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import BinaryIO

__all__ = [
    "AtomicFileSet",
    "atomic_file_set",
    "atomic_write",
    "atomic_write_with",
    "discard_pending",
    "resolve_destination",
]


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _name_max(folder: Path) -> int:
    """The longest file name (bytes) ``folder``'s filesystem takes (255 on ext4, xfs, btrfs, APFS, NTFS)."""
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):  # no pathconf (Windows) or no answer from the filesystem
        return 255


def _sibling(dest: Path, kind: str) -> Path:
    """A fresh hidden name beside ``dest``: ``.NAME.RANDOM.KIND``, ``NAME`` cut to fit the file-name limit.

    The output name plus a prefix and a suffix would exceed the limit for a legal name of 240-odd bytes
    (``[Errno 36] File name too long`` after the whole computation); the name is cut at a character boundary.
    """
    tail = f".{secrets.token_hex(6)}.{kind}"
    room = _name_max(dest.parent) - 1 - len(tail)
    head, size = "", 0
    for ch in dest.name:
        size += len(os.fsencode(ch))
        if size > room:
            break
        head += ch
    return dest.parent / f".{head}{tail}"


def _create_sibling(dest: Path, kind: str) -> tuple[int, str]:
    """Create and open a new hidden file beside ``dest`` (as :func:`tempfile.mkstemp`: ``0o600``, exclusive)."""
    flags = os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_BINARY", 0)
    for _ in range(100):
        path = _sibling(dest, kind)
        try:
            return os.open(path, flags | getattr(os, "O_CLOEXEC", 0), 0o600), str(path)
        except FileExistsError:
            continue  # 48 random bits taken already: draw again
    raise FileExistsError(errno.EEXIST, "no free temporary file name", str(dest.parent))


def resolve_destination(dest: Path) -> Path:
    """The file a write to ``dest`` replaces: ``dest``, or the file its symbolic link (chain) points to.

    Replacing the link itself would turn it into a regular file and leave the file it points to unchanged; a
    careful user who made ``out.ply -> /data/run3/out.ply`` expects the latter to be written, as ``open`` does.

    Raises:
        FileNotFoundError: ``dest`` is a dangling link whose target's folder does not exist.
        OSError: ``dest`` is a link loop.
    """
    if not dest.is_symlink():
        return dest
    target = Path(os.path.realpath(dest))
    if target.is_symlink():  # realpath stops at a loop
        raise OSError(f"path: {str(dest)!r} is a symbolic link loop")
    if not target.parent.is_dir():
        where = f"is a symbolic link to {str(target)!r}, whose folder does not exist"
        raise FileNotFoundError(f"path: {str(dest)!r} {where}")
    return target


class AtomicFileSet:
    """Files staged by :func:`atomic_write_with` inside :func:`atomic_file_set`, committed or discarded together."""

    def __init__(self) -> None:
        self._staged: dict[Path, str] = {}
        self._created_dirs: list[Path] = []

    @property
    def paths(self) -> list[Path]:
        """Destinations staged so far, in the order they were first written."""
        return list(self._staged)

    def mkdir(self, path: str | os.PathLike[str]) -> Path:
        """Create a folder (and missing parents) that is removed again, when empty, if the set is discarded."""
        folder = Path(path)
        missing = []
        for p in (folder, *folder.parents):
            if p.exists():
                break
            missing.append(p)
        folder.mkdir(parents=True, exist_ok=True)
        self._created_dirs += reversed(missing)
        return folder

    def _stage(self, dest: Path, tmp: str) -> None:
        old = self._staged.pop(dest, None)
        if old is not None:
            Path(old).unlink(missing_ok=True)
        self._staged[dest] = tmp

    def _discard(self) -> None:
        for tmp in self._staged.values():
            Path(tmp).unlink(missing_ok=True)
        self._staged.clear()
        for folder in reversed(self._created_dirs):
            with contextlib.suppress(OSError):
                folder.rmdir()  # only when empty: never removes a file of someone else

    def _commit(self) -> None:
        done: list[tuple[Path, str | None]] = []  # (dest, backup of the file it replaced)
        try:
            if before_commit is not None:
                before_commit()
            for dest, tmp in self._staged.items():
                backup = None
                if dest.exists():
                    backup = str(_sibling(dest, "bak"))
                    try:
                        os.link(dest, backup)  # the old file stays visible until the replace
                    except OSError:
                        shutil.copy2(dest, backup)
                try:
                    os.replace(tmp, dest)
                except BaseException:
                    if backup is not None:
                        Path(backup).unlink(missing_ok=True)  # dest still holds the old file
                    raise
                done.append((dest, backup))
        except BaseException:
            for dest, backup in reversed(done):
                if backup is None:
                    dest.unlink(missing_ok=True)
                else:
                    os.replace(backup, dest)
            self._discard()
            raise
        for _, backup in done:
            if backup is not None:
                Path(backup).unlink(missing_ok=True)
        self._staged.clear()


# Called before a file is put in place: the command line's check for a Ctrl-C whose KeyboardInterrupt a finalizer
# dropped (torchmeshmetric.cli._interrupts.raise_pending); None outside the command line.
before_commit: Callable[[], None] | None = None

_ACTIVE: contextvars.ContextVar[AtomicFileSet | None] = contextvars.ContextVar("atomic_file_set", default=None)
# Temporary files being written by atomic_write_with (neither in place, staged nor removed yet), for discard_pending.
_WRITING: set[str] = set()


def discard_pending() -> None:
    """Remove what an exit without unwinding would leave: files being written, the active set's staged files.

    For a process that ends at once (``os._exit``, e.g. the command line at Ctrl-C inside an import, where unwinding
    is unsafe): the ``except`` clauses that normally remove them will not run. The files already in place stay.
    Called from the main thread, it sees the file set of the code it interrupted.

    Example:
        >>> import os, tempfile
        >>> d = tempfile.mkdtemp()
        >>> with atomic_file_set():
        ...     _ = atomic_write(os.path.join(d, "report.json"), "{}")  # staged as a hidden temporary file
        ...     discard_pending()  # what the command line does before an immediate exit
        ...     os.listdir(d)
        []
    """
    for tmp in list(_WRITING):
        Path(tmp).unlink(missing_ok=True)
    files = _ACTIVE.get()
    if files is not None:
        files._discard()


@contextlib.contextmanager
def atomic_file_set() -> Iterator[AtomicFileSet]:
    """Write several files as a unit: all of them appear when the block succeeds, none when it raises.

    Every :func:`atomic_write` / :func:`atomic_write_with` call inside the block (report writers, plots,
    :func:`~torchmeshmetric.data.save_mesh`) stages its file; a staged file is not visible until the block ends.
    Nested blocks join the outermost set.

    Yields:
        The :class:`AtomicFileSet`; its :meth:`~AtomicFileSet.mkdir` creates folders that are removed on failure.

    Example:
        >>> import tempfile, os
        >>> d = tempfile.mkdtemp()
        >>> try:
        ...     with atomic_file_set():
        ...         _ = atomic_write(os.path.join(d, "report.json"), "{}")
        ...         raise OSError(28, "No space left on device")
        ... except OSError:
        ...     pass
        >>> os.listdir(d)
        []
        >>> with atomic_file_set():
        ...     _ = atomic_write(os.path.join(d, "a.txt"), "a")
        ...     _ = atomic_write(os.path.join(d, "b.txt"), "b")
        >>> sorted(os.listdir(d))
        ['a.txt', 'b.txt']
    """
    outer = _ACTIVE.get()
    if outer is not None:
        yield outer
        return
    files = AtomicFileSet()
    token = _ACTIVE.set(files)
    try:
        yield files
    except BaseException:
        _ACTIVE.reset(token)
        files._discard()
        raise
    _ACTIVE.reset(token)
    files._commit()


def atomic_write_with(
    path: str | os.PathLike[str],
    write: Callable[[BinaryIO], object],
    *,
    overwrite: bool = False,
    join_file_set: bool = True,
) -> Path:
    """Create ``path`` atomically from ``write(binary_file)``.

    Args:
        path: destination file; its folder must exist.
        write: writes the content to the open binary temporary file.
        overwrite: replace an existing file (default ``False``: never overwrite a user's file unasked).
        join_file_set: inside :func:`atomic_file_set`, stage the file into the set (default); ``False`` writes it
            at once (e.g. a cache entry that is worth keeping whatever happens to the outputs).

    Returns:
        The destination path, as given (a symbolic link stays one: the file it points to is replaced).

    Raises:
        FileExistsError: ``path`` exists (or is a symbolic link, dangling or not) and ``overwrite`` is ``False``.
        FileNotFoundError, NotADirectoryError, PermissionError, IsADirectoryError: the destination folder is
            missing, a file, or unwritable, or ``path`` is a folder; ``path`` is a dangling link whose target's
            folder is missing.
    """
    given = Path(path)
    if given.is_dir():
        raise IsADirectoryError(f"path: {str(given)!r} is a directory, expected a file path")
    # A link counts as an existing file even when it dangles (exists() follows it and says False).
    if (given.exists() or given.is_symlink()) and not overwrite:
        raise FileExistsError(f"path: {str(given)!r} already exists (pass overwrite=True / --overwrite to replace it)")
    dest = resolve_destination(given)
    folder = dest.parent if str(dest.parent) else Path(".")
    if not folder.is_dir():
        raise missing_folder_error(folder)
    fd, tmp = _create_sibling(folder / dest.name, "tmp")
    _WRITING.add(tmp)
    try:
        os.chmod(tmp, dest.stat().st_mode & 0o777 if dest.exists() else 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        files = _ACTIVE.get() if join_file_set else None
        if files is not None:
            files._stage(dest, tmp)
        else:
            if before_commit is not None:
                before_commit()
            os.replace(tmp, dest)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        _WRITING.discard(tmp)
    return given


def blocking_file(folder: Path) -> Path | None:
    """The regular file that ``folder`` is, or lies below (``notes.txt`` for ``notes.txt/out``), or ``None``."""
    for p in (folder, *folder.parents):
        if p.exists():
            return None if p.is_dir() else p
    return None


def missing_folder_error(folder: Path) -> OSError:
    """The error for a destination folder that is not a folder: missing, or (below) a regular file."""
    blocker = blocking_file(folder)
    if blocker is not None:
        where = f" (cannot write into {str(folder)!r})" if blocker != folder else ""
        return NotADirectoryError(f"path: {str(blocker)!r} is a file, not a folder{where}")
    return FileNotFoundError(f"path: folder {str(folder)!r} does not exist")


def atomic_write(
    path: str | os.PathLike[str], data: str | bytes, *, overwrite: bool = False, join_file_set: bool = True
) -> Path:
    """Write text (UTF-8) or bytes to ``path`` atomically (see :func:`atomic_write_with`).

    Example:
        >>> import tempfile, os
        >>> d = tempfile.mkdtemp()
        >>> p = atomic_write(os.path.join(d, "a.txt"), "hello")
        >>> p.read_text(), sorted(os.listdir(d))
        ('hello', ['a.txt'])
    """
    payload = data.encode("utf-8") if isinstance(data, str) else data
    return atomic_write_with(path, lambda fh: fh.write(payload), overwrite=overwrite, join_file_set=join_file_set)
