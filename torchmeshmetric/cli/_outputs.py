"""Where a command's outputs go: the checks made before any work, and the writing of them as one set.

Light on purpose (no torch, no evaluation system): every command imports it, the fast ones (``ctc``, ``mpeg``,
``sample``) included.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

from torchmeshmetric._atomic import atomic_file_set, blocking_file, resolve_destination

__all__ = [
    "CLIError",
    "check_appended_csv",
    "check_creatable",
    "check_folder",
    "check_mesh_suffixes",
    "check_writable",
    "folder_inputs",
    "make_folder",
    "output_set",
]


class CLIError(Exception):
    """An error reported to the user as one line (exit code 1)."""


def check_folder(folder: Path, what: str, *, may_create: bool = False) -> None:
    """An output folder: existing (or, with ``may_create``, missing), never a file nor below a file."""
    try:
        exists = folder.is_dir()
    except PermissionError:  # a folder above it cannot be searched (review X, F14: a bare "[Errno 13]")
        raise CLIError(f"{what} {str(folder)!r}: a folder above it cannot be searched (permission denied)") from None
    if not exists:
        blocker = blocking_file(folder)
        if blocker is not None:
            raise CLIError(f"{what} {str(folder)!r}: {str(blocker)!r} is a file, not a folder")
        if not may_create:
            raise CLIError(f"{what} {str(folder)!r} does not exist")


def check_creatable(folder: Path, what: str) -> None:
    """A missing output folder that this user can create: its nearest existing folder writable and searchable.

    :func:`check_folder` with ``may_create`` checks that nothing is in the way, not that the folder can be made:
    ``demo --out-dir ro/d`` made and simplified the sequence first, then said "cannot create it (Permission
    denied)" (review X, F15). An existing folder is left to the writes' own checks.
    """
    if folder.is_dir():
        return
    above = next((p for p in folder.parents if p.is_dir()), Path("."))  # "." exists (the current folder)
    if not os.access(above, os.W_OK | os.X_OK):
        raise CLIError(f"{what} {str(folder)!r}: cannot create it (folder {str(above)!r} is not writable)")


def check_appended_csv(path: Path, header: str) -> None:
    """An ``--output-csv`` the run will append a row to: its first line ``header`` (or none) and appendable, now.

    Both are found before the work (``mpeg``, ``sample``): a file of another header, or one that cannot be opened
    for appending (review X, F15: a read-only file was found after the comparison).

    Raises:
        CLIError: ``--output-csv: ...`` (another header) or ``--output-csv 'PATH': cannot append to it (...)``.
    """
    from torchmeshmetric.mpeg.comparison.csv_rows import CsvHeaderError, check_csv_header

    try:
        check_csv_header(path, header)
    except CsvHeaderError as exc:
        raise CLIError(f"--output-csv: {exc}") from exc
    except OSError as exc:
        raise CLIError(f"--output-csv {str(path)!r}: cannot append to it ({exc.strerror})") from exc


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


def check_mesh_suffixes(paths: Sequence[Path], option: str, *, names_from: str | None = None) -> None:
    """Mesh outputs: each suffix one :func:`~torchmeshmetric.data.io.save_mesh` writes (checked before any work).

    Args:
        paths: the mesh files the command writes.
        option: the option that names them (``--out``), or their folder (``--output``).
        names_from: the option whose file names the outputs keep (``simplify``'s ``--input``), for the message.

    Raises:
        CLIError: naming the option, the file and the writable formats.
    """
    from torchmeshmetric.data.io import WRITABLE_MESH_SUFFIXES  # torch: only the commands that write meshes

    formats = ", ".join(WRITABLE_MESH_SUFFIXES)
    for path in paths:
        suffix = path.suffix
        if suffix.lower() in WRITABLE_MESH_SUFFIXES:
            continue
        what = f"cannot write a mesh as {suffix!r}" if suffix else "no mesh suffix"
        if names_from is None:
            raise CLIError(f"{option} {str(path)!r}: {what}; writable formats: {formats}")
        raise CLIError(
            f"{option} {str(path.parent)!r}: the frame {path.name!r}: {what} (the simplified frames keep the file "
            f"names of {names_from}); writable formats: {formats}"
        )


def _identity(path: Path) -> tuple[object, ...]:
    """What makes two paths one file: an existing file's device and inode (any spelling or link), else its path."""
    try:
        st = os.stat(path)
    except OSError:
        return ("path", os.path.normcase(os.path.realpath(path)))
    return ("inode", st.st_dev, st.st_ino)


def folder_inputs(option: str, folder: str | os.PathLike[str] | None) -> list[tuple[str, Path]]:
    """The frames of an input folder, as :func:`check_writable` inputs (none where it is no folder).

    A folder whose frames cannot be listed (it holds no mesh file, a frame is a broken link) gives none: this is the
    outputs' check, and the command's reading of its inputs reports that problem, naming the option that gave the
    folder (reported from here, the message named ``paths``, a parameter of ``list_frames``, and came even without
    an output: found by review O).
    """
    if folder is None or not Path(folder).is_dir():
        return []
    from torchmeshmetric.data.frames import list_frames
    from torchmeshmetric.data.mesh_file import MeshFileError

    try:
        return [(option, p) for p in list_frames(folder)]
    except MeshFileError:
        return []


def _labels(what: str | Sequence[str], n: int) -> list[str]:
    return [what] * n if isinstance(what, str) else list(what)


def check_writable(
    paths: Sequence[Path],
    overwrite: bool,
    *,
    inputs: Iterable[tuple[str, str | os.PathLike[str] | None]],
    what: str | Sequence[str] = "output",
    appended: Sequence[tuple[str, Path]] = (),
) -> None:
    """The one check of a command's output set, made before any computation (every command that writes calls it).

    In this order: no output is one of the command's input files (the same file under any spelling, symbolic or
    hard link: ``--overwrite`` replaces earlier outputs, never inputs); the outputs are distinct files (two options
    naming one file would lose one of them); each output's folder exists and is writable, the output is not a
    folder, and it exists only with ``overwrite``. A symbolic link counts as an existing output, dangling or not;
    with ``overwrite`` the file it points to is replaced (the link is kept), so that file's folder must exist and be
    writable. Files in ``appended`` (a CSV mmetric appends rows to) take part in the first two checks and may exist.

    Args:
        paths: the files the command replaces or creates.
        overwrite: ``--overwrite`` was given.
        inputs: ``(option, path)`` of every file the command reads (``None`` paths are skipped); a folder's files
            are listed by the caller.
        what: the option naming every path, or one option per path (for messages).
        appended: ``(option, path)`` of files the command appends to.

    Raises:
        CLIError: naming the option(s) and the file.
    """
    labelled = [*zip(_labels(what, len(paths)), paths, strict=True), *appended]
    read: dict[tuple[object, ...], tuple[str, str]] = {}
    for option, path in inputs:
        if path is not None:
            read.setdefault(_identity(Path(path)), (option, str(path)))
    seen: dict[tuple[object, ...], tuple[str, Path]] = {}
    for option, path in labelled:
        key = _identity(path)
        if key in read:
            source, given = read[key]
            raise CLIError(
                f"{option} {str(path)!r} is the input {source} {given!r}: a command never writes its inputs "
                "(--overwrite replaces earlier outputs only); choose another output file"
            )
        if key in seen:
            other, first = seen[key]
            raise CLIError(
                f"{option} {str(path)!r} is also {other} {str(first)!r}: the outputs of one run must be distinct files"
            )
        seen[key] = (option, path)
    for (option, path), replace in zip(labelled, [overwrite] * len(paths) + [True] * len(appended), strict=True):
        folder = path.parent if str(path.parent) else Path(".")
        check_folder(folder, f"{option} {str(path)!r}: output folder")  # the option named, as in every message here
        if not os.access(folder, os.X_OK):  # else is_dir() below raised a bare "[Errno 13]" (review X, F14)
            raise CLIError(
                f"{option} {str(path)!r}: output folder {str(folder)!r} cannot be searched (permission denied)"
            )
        if path.is_dir():
            raise CLIError(f"{option} {str(path)!r} is a directory, expected a file")
        # A symbolic link is an existing output even when it dangles (exists() follows it and says False).
        if (path.exists() or path.is_symlink()) and not replace:
            raise CLIError(f"{option} {str(path)!r} already exists (pass --overwrite to replace it)")
        if path.is_symlink():
            folder = _link_folder(option, path)  # the file it points to is replaced, in that file's folder
        if not os.access(folder, os.W_OK):
            raise CLIError(f"{option} {str(path)!r}: output folder {str(folder)!r} is not writable")


def _link_folder(option: str, path: Path) -> Path:
    """The folder of the file an output link points to (written there, the link kept), or an error naming it."""
    try:
        target = resolve_destination(path)
    except OSError as exc:
        _, _, why = str(exc).partition(": ")
        raise CLIError(f"{option} {why}") from exc
    return target.parent
