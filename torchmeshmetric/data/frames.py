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


def natural_key(path: str | os.PathLike) -> tuple[object, ...]:
    """Sort key that orders embedded numbers by value: ``frame2 < frame10``.

    Example:
        >>> sorted(["f10.obj", "f2.obj", "f1.obj"], key=natural_key)
        ['f1.obj', 'f2.obj', 'f10.obj']
    """
    parts = re.split(r"(\d+)", os.fspath(path))
    return tuple((0, int(p), p) if p.isdigit() else (1, 0, p.lower()) for p in parts)


def frame_numbers(paths: Sequence[str | os.PathLike]) -> list[int] | None:
    """The frame number of each file: the last number in its name without the suffix, as :func:`natural_key` reads it.

    ``None`` when a file's name holds no number or two files share one (such frames pair by position only).

    Example:
        >>> frame_numbers(["frame_000.ply", "frame_002.ply", "take2_frame_010.obj"])
        [0, 2, 10]
        >>> frame_numbers(["a.ply", "b.ply"]) is None
        True
    """
    numbers = []
    for path in paths:
        found = [part for part in natural_key(Path(path).stem) if isinstance(part, tuple) and part[0] == 0]
        if not found:
            return None
        numbers.append(int(found[-1][1]))
    return numbers if len(set(numbers)) == len(numbers) else None


def list_frames(paths: PathsLike) -> list[Path]:
    r"""Resolve a directory, glob pattern, single file or list of files into frame paths in natural order.

    A directory yields its files with a mesh suffix (:data:`MESH_SUFFIXES`), leaving hidden files (names starting
    with ``.``, such as an editor's ``.frame1.obj``) out, as a glob pattern does; a glob yields its matches; a list is
    kept in the given order (an explicit order is respected). A broken symbolic link among the frames is refused:
    leaving it out would give every frame after it the number of the one before.

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
        if p.is_dir():
            named = [q for q in p.iterdir() if q.suffix.lower() in MESH_SUFFIXES and not q.name.startswith(".")]
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
