"""What every mesh reader shares: the error type, the suffixes, the file and text checks, the checks of the result.

Each format has one reader (:mod:`~torchmeshmetric.data.obj`, :mod:`~torchmeshmetric.data.off`,
:mod:`~torchmeshmetric.data.ply`, :mod:`~torchmeshmetric.data.trimesh_formats`); they all raise
:class:`MeshFileError` naming the file (and the line or element), and :func:`check_mesh` checks what any of them read.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import torch

__all__ = [
    "MESH_SUFFIXES",
    "MeshFileError",
    "check_dtype_range",
    "check_mesh",
    "check_text",
    "check_vertices",
    "existing_mesh_file",
    "not_a_mesh",
    "plain_float",
    "plain_int",
    "text_lines",
    "to_tensor",
    "without_bom",
    "values_per_line",
]


class MeshFileError(ValueError):
    """A mesh file is missing, unreadable, corrupt, empty or not made of triangles (the message names the file).

    Example:
        >>> import os, tempfile
        >>> from torchmeshmetric import load_mesh
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     try:
        ...         load_mesh(os.path.join(folder, "missing.obj"))
        ...     except MeshFileError as error:  # a ValueError too
        ...         print(str(error).replace(folder, "FOLDER"))
        path: mesh file 'FOLDER/missing.obj' does not exist
    """


MESH_SUFFIXES: tuple[str, ...] = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")
"""File suffixes recognised as mesh frames (case-insensitive)."""


def not_a_mesh(p: Path, why: str) -> MeshFileError:
    """The error for a file that is no mesh file of its format."""
    return MeshFileError(f"path: '{p}' is not a mesh file ({why})")


def without_bom(data: bytes) -> bytes:
    r"""``data`` without a leading UTF-8 byte-order mark: every reader of the package skips it (it is no statement).

    Example:
        >>> without_bom(b"\xef\xbb\xbfv 0 0 0\n")
        b'v 0 0 0\n'
    """
    return data.removeprefix(b"\xef\xbb\xbf")


def text_lines(p: Path, data: bytes) -> list[bytes]:
    """Lines of a text mesh format; binary data (NUL or other control bytes) is refused as not a mesh file."""
    check_text(p, data)
    return without_bom(data).splitlines()


_CONTROL = bytes([*range(0, 9), *range(14, 32), 127])


def check_text(p: Path, data: bytes) -> None:
    """Refuse binary data (NUL or other control bytes) in a text format, naming its line and byte."""
    if len(data.translate(None, _CONTROL)) == len(data):
        return  # no control byte (bytes.translate is one C pass; a regex search is ten times slower)
    control = re.search(rb"[\x00-\x08\x0e-\x1f\x7f]", data)
    if control is not None:
        line = data.count(b"\n", 0, control.start()) + 1
        raise not_a_mesh(p, f"binary data at line {line}, byte {control.start()}")


def plain_float(token: bytes) -> float:
    """``float(token)``, never with an underscore: Python reads ``1_0`` as 10, numpy's parser and others refuse it.

    Raises:
        ValueError: not a number (the caller names the file and line).
    """
    if b"_" in token:
        raise ValueError(token)
    return float(token)


def plain_int(token: bytes) -> int:
    """``int(token)``, never with an underscore (see :func:`plain_float`)."""
    if b"_" in token:
        raise ValueError(token)
    return int(token)


def values_per_line(buf: np.ndarray, starts: np.ndarray, *, chunk: int = 1 << 20) -> np.ndarray:
    """How many whitespace-separated values each line holds, vectorised (a few passes over the bytes).

    ``buf`` holds text whose every line ends with its newline (control bytes other than whitespace refused, so
    ``<= 32`` is whitespace); ``starts`` is each line's first byte. A value starts where text follows a space.
    Runs of whole lines of about ``chunk`` bytes keep the temporaries in the cache: twice as fast as one pass over
    an 80 MB file.
    """
    out = np.empty(starts.shape[0], dtype=np.int32)
    cuts = np.unique(np.append(np.searchsorted(starts, np.arange(0, buf.shape[0], chunk)), starts.shape[0]))
    for a, b in zip(cuts[:-1].tolist(), cuts[1:].tolist(), strict=True):
        lo, hi = int(starts[a]), int(starts[b]) if b < starts.shape[0] else buf.shape[0]
        space = buf[lo:hi] <= 32
        rise = np.empty(hi - lo, dtype=bool)
        rise[0] = not space[0]
        np.greater(space[:-1], space[1:], out=rise[1:])
        out[a:b] = np.add.reduceat(rise, starts[a:b] - lo, dtype=np.int32)
    return out


def existing_mesh_file(path: str | os.PathLike) -> Path:
    """``path`` as a ``Path`` when it is a non-empty file with a mesh suffix; else the error saying what it is.

    Raises:
        MeshFileError: a directory, a missing file, an unsupported suffix, an empty file, or a file that cannot be
            read (permission denied, on the file or a folder above it).

    Example:
        >>> import tempfile
        >>> existing_mesh_file(tempfile.mkdtemp())  # doctest: +ELLIPSIS
        Traceback (most recent call last):
            ...
        torchmeshmetric.data.mesh_file.MeshFileError: path: '...' is a directory, not a mesh file
    """
    p = Path(path)
    try:
        if p.is_dir():
            raise MeshFileError(f"path: '{p}' is a directory, not a mesh file")
        if not p.is_file():
            raise MeshFileError(f"path: mesh file '{p}' does not exist")
        if p.suffix.lower() not in MESH_SUFFIXES:
            raise MeshFileError(f"path: '{p}' has unsupported suffix '{p.suffix}' (expected one of {MESH_SUFFIXES})")
        if p.stat().st_size == 0:
            raise MeshFileError(f"path: mesh file '{p}' is empty (0 bytes)")
        with open(p, "rb"):  # readable: the readers' own open said a bare "[Errno 13] Permission denied: 'x'"
            pass
    except PermissionError as exc:  # the file, or a folder above it that cannot be searched (review X, F14)
        raise MeshFileError(f"path: mesh file '{p}' cannot be read (permission denied)") from exc
    return p


def check_mesh(p: Path, verts: np.ndarray, faces: np.ndarray, lines: np.ndarray | None) -> None:
    """What every mesh file must satisfy, whatever its format: faces, triangles, finite vertices, valid indices."""
    if faces.ndim != 2 or faces.shape[0] == 0:
        raise MeshFileError(f"path: mesh file '{p}' has no faces ({verts.shape[0]} vertices)")
    if faces.shape[1] != 3:
        raise MeshFileError(f"path: mesh file '{p}' has {faces.shape[1]}-sided faces; expected triangles")
    if verts.ndim != 2 or verts.shape[1] != 3:
        raise MeshFileError(f"path: mesh file '{p}' has vertices of shape {verts.shape}; expected (V, 3)")
    check_vertices(p, verts, "vertex", lines)
    lo, hi = int(faces.min()), int(faces.max())
    if lo < 0 or hi >= verts.shape[0]:
        bad = int(np.nonzero((faces < 0).any(1) | (faces >= verts.shape[0]).any(1))[0][0])
        raise MeshFileError(
            f"path: mesh file '{p}' face {bad} has vertex indices {faces[bad].tolist()} outside "
            f"[0, {verts.shape[0] - 1}]"
        )


def check_vertices(p: Path, verts: np.ndarray, what: str, lines: np.ndarray | None = None) -> None:
    """Every coordinate finite; the message names the first bad vertex (and its line when known)."""
    if np.isfinite(verts.sum()) or np.isfinite(verts).all():
        return  # a finite sum: every value finite (the sum of finite float64 coordinates of a mesh cannot overflow)
    bad = ~np.isfinite(verts).all(axis=1)
    if bad.any():
        i = int(np.nonzero(bad)[0][0])
        where = f" (line {int(lines[i])})" if lines is not None else ""
        raise MeshFileError(
            f"path: mesh file '{p}' {what} {i}{where} has non-finite coordinates {verts[i].tolist()} "
            f"({int(bad.sum())} such vertices)"
        )


def check_dtype_range(
    p: Path,
    verts: np.ndarray,
    dtype: torch.dtype,
    lines: np.ndarray | None = None,
    hint: str | None = None,
    *,
    what: tuple[str, str, str] = ("vertex", "coordinates", "vertices"),
) -> None:
    """Refuse coordinates that ``dtype`` cannot hold (they would become Inf), naming the first one and its line.

    A value beyond the dtype's largest finite one but within half a unit of it rounds to that value, not to Inf: the
    shortest text of float32's largest, ``3.4028235e+38``, is such a value, and a float32 mesh written as OFF or OBJ
    did not load back (found by review). So the test is the cast itself, as the PLY reader's.

    ``what`` names a row, its values and the rows in the message: ``("texture coordinate", "values", "'vt' lines")``
    for UVs.
    """
    finfo_max = torch.finfo(dtype).max
    if verts.size == 0 or float(np.abs(verts).max()) <= finfo_max:
        return  # the common case, without a cast
    with np.errstate(over="ignore"):
        big = np.isinf(verts.astype(_NUMPY_DTYPES.get(dtype, np.float64))).any(axis=1)
    if not big.any():
        return
    i = int(np.nonzero(big)[0][0])
    where = f" line {int(lines[i])}:" if lines is not None else ""
    raise MeshFileError(
        f"path: mesh file '{p}'{where} {what[0]} {i} has {what[1]} up to "
        f"{float(np.abs(verts).max()):.8g}, beyond the range of {dtype} (max {finfo_max:.8g}; "
        f"{int(big.sum())} such {what[2]}); {hint or 'load it with dtype=torch.float64'}"
    )


_NUMPY_DTYPES = {torch.float32: np.float32, torch.float64: np.float64}


def to_tensor(verts: np.ndarray, dtype: torch.dtype) -> torch.Tensor:
    """``verts`` as a ``dtype`` tensor, converted by numpy (torch's ``.to`` wakes its thread pool: 20 ms here)."""
    target = _NUMPY_DTYPES.get(dtype)
    if target is None:
        return torch.from_numpy(verts).to(dtype)
    return torch.from_numpy(np.ascontiguousarray(verts, dtype=target))
