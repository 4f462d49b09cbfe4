"""The frames of a sequence: a directory, a glob pattern, a file or a list, in natural order."""

from __future__ import annotations

import glob as _glob
import os
import re
from collections.abc import Sequence
from pathlib import Path

from torchmeshmetric.data.mesh_file import MESH_SUFFIXES, MeshFileError

__all__ = ["PathsLike", "frame_numbers", "list_frames", "natural_key"]


PathsLike = str | os.PathLike | Sequence[str | os.PathLike]
"""A directory, a glob pattern, a single file, or a list of files."""


_NUMBER = re.compile(r"(\d+)")
"""A number in a file name: a run of digits (no sign, no decimal point: ``v1.2`` holds 1 and 2)."""


def natural_key(path: str | os.PathLike) -> tuple[object, ...]:
    """Sort key that orders embedded numbers by value: ``frame2 < frame10``.

    Args:
        path: a file name or path.

    Returns:
        A tuple comparing runs of digits by their value and other text case-insensitively.

    Example:
        >>> sorted(["f10.obj", "f2.obj", "f1.obj"], key=natural_key)
        ['f1.obj', 'f2.obj', 'f10.obj']
    """
    parts = _NUMBER.split(os.fspath(path))
    return tuple((0, int(p), p) if p.isdigit() else (1, 0, p.lower()) for p in parts)


def frame_numbers(paths: Sequence[str | os.PathLike]) -> list[int] | None:
    """The frame number of each file: the first number position of the names whose values all differ.

    The numbers of each name without its suffix are read left to right (as :func:`natural_key` reads them); the
    frame number is the first position at which every file's number differs from every other's. A position whose
    number repeats, such as a constant ``seq2``, ``r1`` or ``v1.2``, is skipped, and so is a number after the frame
    number (a simplifier's face count, ``frame_0001_f1007.ply``) since the frame number comes first. Only positions
    that every name has are read.

    ``None`` when a file's name holds no number or no position has distinct numbers (such frames pair by position
    only), and for a single file (one frame pairs with one frame: there is nothing to tell apart).

    Example:
        >>> frame_numbers(["seq2_frame_000.ply", "seq2_frame_002.ply", "seq2_frame_010.obj"])
        [0, 2, 10]
        >>> frame_numbers(["frame_0000_f1000.ply", "frame_0001_f1007.ply"])
        [0, 1]
        >>> frame_numbers(["a.ply", "b.ply"]) is None
        True
    """
    if len(paths) < 2:
        return None
    tokens = [[int(n) for n in _NUMBER.findall(Path(p).stem)] for p in paths]
    for position in range(min(len(t) for t in tokens)):
        numbers = [t[position] for t in tokens]
        if len(set(numbers)) == len(numbers):
            return numbers
    return None


def list_frames(paths: PathsLike) -> list[Path]:
    r"""Resolve a directory, glob pattern, single file or list of files into frame paths in natural order.

    A directory yields its files with a mesh suffix (:data:`MESH_SUFFIXES`), leaving hidden files (names starting
    with ``.``, such as an editor's ``.frame1.obj``) out, as a glob pattern does; a glob yields its matches; a list is
    kept in the given order (an explicit order is respected). A broken symbolic link among the frames is refused:
    leaving it out would give every frame after it the number of the one before.

    Args:
        paths: a directory, a glob pattern, a single mesh file, or a list of mesh files.

    Returns:
        The frame files, in natural order (a list: in its own order).

    Raises:
        MeshFileError: an empty path, nothing matches, a listed file does not exist, or a frame is a broken
            symbolic link.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> for n in (10, 2, 1):
        ...     _ = (d / f"frame{n}.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        >>> " ".join(p.name for p in list_frames(d))
        'frame1.obj frame2.obj frame10.obj'
    """
    if isinstance(paths, (str, os.PathLike)):
        if not os.fspath(paths).strip():  # Path("") is the current folder: never read it for an unset name
            raise MeshFileError(f"paths: expected a directory, a glob pattern or a mesh file, found {paths!r}")
        p = Path(paths)
        try:
            is_dir = p.is_dir()
            listed = list(p.iterdir()) if is_dir else []
        except PermissionError as exc:  # said a bare "[Errno 13] Permission denied: 'd'" (review X, F14)
            raise MeshFileError(f"paths: directory '{p}' cannot be read (permission denied)") from exc
        if is_dir:
            named = [q for q in listed if q.suffix.lower() in MESH_SUFFIXES and not q.name.startswith(".")]
            _refuse_broken_links(named)
            found = [q for q in named if q.is_file()]
            if not found:
                raise MeshFileError(f"paths: directory '{p}' holds no mesh files (suffixes {', '.join(MESH_SUFFIXES)})")
            return sorted(found, key=natural_key)
        if p.is_file():
            return [p]
        if _glob.has_magic(os.fspath(p)):
            matched = [Path(m) for m in _glob.glob(os.fspath(p))]
            _refuse_broken_links(matched)
            matches = [q for q in matched if q.is_file()]
            if not matches:
                raise MeshFileError(f"paths: glob pattern '{p}' matches no files")
            return sorted(matches, key=natural_key)
        raise MeshFileError(f"paths: '{p}' does not exist (expected a directory, a glob pattern or a mesh file)")
    out = [Path(q) for q in paths]
    if not out:
        raise MeshFileError("paths: the list of frame files is empty")
    for q in out:
        if q.is_dir():
            raise MeshFileError(f"paths: '{q}' is a directory, not a mesh file")
        _refuse_broken_links([q])
        if not q.is_file():
            raise MeshFileError(f"paths: file '{q}' does not exist")
    return out


def _refuse_broken_links(paths: list[Path]) -> None:
    """Refuse a frame that is a symbolic link to nothing (``is_file()`` is false for it, so it would be dropped)."""
    for q in sorted(paths, key=natural_key):
        if q.is_symlink() and not q.exists():
            raise MeshFileError(
                f"paths: frame '{q}' is a broken symbolic link (to '{os.readlink(q)}'); leaving it out would "
                "renumber the frames after it: restore its target or remove the link"
            )
