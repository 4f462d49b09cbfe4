"""Mesh and sequence I/O: load frames in natural order, save atomically.

OBJ and OFF are parsed here (line-level errors); PLY, STL and GLB/GLTF are read with trimesh and ``process=False``.
Either way vertex order and duplicate vertices survive exactly as stored (a registration or evaluation refers to
vertices by index), and what a file holds is checked against what it declares (see :func:`load_mesh`). Supported:
OBJ, PLY, OFF, STL, GLB/GLTF (a scene is concatenated into one mesh).
"""

from __future__ import annotations

import glob as _glob
import io
import os
import queue
import re
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any, TypeVar, cast, overload

import numpy as np
import torch

from torchmeshmetric._atomic import atomic_write, missing_folder_error
from torchmeshmetric._checks import EmptyInputError, ShapeError
from torchmeshmetric.data.obj import MeshFileError, check_text, not_a_mesh, parse_obj, text_lines
from torchmeshmetric.structures import Mesh

__all__ = [
    "MESH_SUFFIXES",
    "MeshFileError",
    "PathsLike",
    "Prefetcher",
    "iter_sequence",
    "list_frames",
    "load_mesh",
    "load_sequence",
    "natural_key",
    "prefetch_frames",
    "read_mesh_arrays",
    "save_mesh",
]

MESH_SUFFIXES: tuple[str, ...] = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")
"""File suffixes recognised as mesh frames (case-insensitive)."""

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


def list_frames(paths: PathsLike) -> list[Path]:
    r"""Resolve a directory, glob pattern, single file or list of files into frame paths in natural order.

    A directory yields its files with a mesh suffix (:data:`MESH_SUFFIXES`); a glob yields its matches; a list is kept
    in the given order (an explicit order is respected).

    Raises:
        MeshFileError: nothing matches, or a listed file does not exist.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> for n in (10, 2, 1):
        ...     _ = (d / f"frame{n}.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        >>> " ".join(p.name for p in list_frames(d))
        'frame1.obj frame2.obj frame10.obj'
    """
    if isinstance(paths, (str, os.PathLike)):
        p = Path(paths)
        if p.is_dir():
            found = [q for q in p.iterdir() if q.is_file() and q.suffix.lower() in MESH_SUFFIXES]
            if not found:
                raise MeshFileError(f"paths: directory '{p}' holds no mesh files (suffixes {', '.join(MESH_SUFFIXES)})")
            return sorted(found, key=natural_key)
        if p.is_file():
            return [p]
        if _glob.has_magic(os.fspath(p)):
            matches = [Path(m) for m in _glob.glob(os.fspath(p)) if Path(m).is_file()]
            if not matches:
                raise MeshFileError(f"paths: glob pattern '{p}' matches no files")
            return sorted(matches, key=natural_key)
        raise MeshFileError(f"paths: '{p}' does not exist (expected a directory, a glob pattern or a mesh file)")
    out = [Path(q) for q in paths]
    if not out:
        raise MeshFileError("paths: the list of frame files is empty")
    for q in out:
        if not q.is_file():
            raise MeshFileError(f"paths: file '{q}' does not exist")
    return out


def load_mesh(path: str | os.PathLike, *, dtype: torch.dtype = torch.float32) -> Mesh:
    r"""Load one triangle mesh without any processing (vertex order and duplicates are kept).

    What a file holds is checked against what it declares and what its format allows (see the docs' *Bad input*
    page): OBJ and OFF are parsed here, line by line (OBJ: 3 coordinates per vertex, optional ``w`` or colour;
    1-based face indices, negative ones counting back from the last vertex defined, 0 and out-of-range ones
    refused; OFF: the header's vertex and face counts). PLY, STL and GLB/GLTF are read with trimesh, and the PLY
    header's element counts and the binary STL's triangle count are checked. Text is read as UTF-8, or as Latin-1
    where it is not (a comment's encoding never matters); binary data in a text format is "not a mesh file".
    Every vertex must be finite, also once converted to ``dtype``.

    Args:
        path: an OBJ, PLY, OFF, STL or GLB/GLTF file. A multi-mesh scene is concatenated.
        dtype: vertex dtype of the result (default ``float32``).

    Returns:
        The mesh on the CPU.

    Raises:
        MeshFileError: the file is missing, of an unknown format, not a mesh file, corrupt or truncated, empty,
            has non-triangle faces, invalid face indices or non-finite coordinates (the message names the file and,
            where there is one, the line or element).

    Example:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "tri.obj"
        >>> _ = p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -1\n")
        >>> load_mesh(p)
        Mesh(num_verts=3, num_faces=1, dtype=torch.float32, device=cpu)
    """
    p = _existing(path)
    verts, faces, lines = _read_geometry(p, p.suffix.lower())
    check_mesh(p, verts, faces, lines)
    check_dtype_range(p, verts, dtype, lines)
    return Mesh(to_tensor(verts, dtype), torch.from_numpy(faces), validate=False)


_NUMPY_DTYPES = {torch.float32: np.float32, torch.float64: np.float64}


def to_tensor(verts: np.ndarray, dtype: torch.dtype) -> torch.Tensor:
    """``verts`` as a ``dtype`` tensor, converted by numpy (torch's ``.to`` wakes its thread pool: 20 ms here)."""
    target = _NUMPY_DTYPES.get(dtype)
    if target is None:
        return torch.from_numpy(verts).to(dtype)
    return torch.from_numpy(np.ascontiguousarray(verts, dtype=target))


def _read_geometry(p: Path, suffix: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(verts, faces, vertex lines or None)`` of an existing, non-empty mesh file, through its one reader."""
    if suffix == ".obj":
        return _parse_obj(p, p.read_bytes())
    if suffix == ".off":
        return (*_parse_off(p, p.read_bytes()), None)
    if suffix == ".ply":
        fast = _read_ply_fast(p)
        if fast is not None:
            return fast[0], fast[1], None
    verts, faces, _ = _load_with_trimesh(p, suffix)
    return verts, faces, None


def read_mesh_arrays(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(verts, faces, colors)`` of a mesh file through its format's one reader, every check of :func:`load_mesh`.

    The same reader and checks as :func:`load_mesh` (which needs no colours); ``colors`` are ``(V, 3)`` per-vertex
    colours in ``[0, 255]`` from a PLY's ``red green blue`` (or trimesh's reading of other formats), else ``None``.
    OBJ colours are read by :func:`~torchmeshmetric.mpeg.load_textured_mesh`.
    """
    p = _existing(path)
    suffix = p.suffix.lower()
    colors = None
    if suffix == ".obj":
        verts, faces, lines = _parse_obj(p, p.read_bytes())
    elif suffix == ".off":
        (verts, faces), lines = _parse_off(p, p.read_bytes()), None
    else:
        fast = _read_ply_fast(p) if suffix == ".ply" else None
        verts, faces, colors = fast if fast is not None else _load_with_trimesh(p, suffix)
        lines = None
    check_mesh(p, verts, faces, lines)
    return verts, faces, colors


def _existing(path: str | os.PathLike) -> Path:
    p = Path(path)
    if not p.is_file():
        raise MeshFileError(f"path: mesh file '{p}' does not exist")
    if p.suffix.lower() not in MESH_SUFFIXES:
        raise MeshFileError(f"path: '{p}' has unsupported suffix '{p.suffix}' (expected one of {MESH_SUFFIXES})")
    if p.stat().st_size == 0:
        raise MeshFileError(f"path: mesh file '{p}' is empty (0 bytes)")
    return p


def check_mesh(p: Path, verts: np.ndarray, faces: np.ndarray, lines: np.ndarray | None) -> None:
    """What every mesh file must satisfy, whatever its format: faces, triangles, finite vertices, valid indices."""
    if faces.ndim != 2 or faces.shape[0] == 0:
        raise MeshFileError(f"path: mesh file '{p}' has no faces ({verts.shape[0]} vertices)")
    if faces.shape[1] != 3:
        raise MeshFileError(f"path: mesh file '{p}' has {faces.shape[1]}-sided faces; expected triangles")
    if verts.ndim != 2 or verts.shape[1] != 3:
        raise MeshFileError(f"path: mesh file '{p}' has vertices of shape {verts.shape}; expected (V, 3)")
    _check_vertices(p, verts, "vertex", lines)
    lo, hi = int(faces.min()), int(faces.max())
    if lo < 0 or hi >= verts.shape[0]:
        bad = int(np.nonzero((faces < 0).any(1) | (faces >= verts.shape[0]).any(1))[0][0])
        raise MeshFileError(
            f"path: mesh file '{p}' face {bad} has vertex indices {faces[bad].tolist()} outside "
            f"[0, {verts.shape[0] - 1}]"
        )


def _not_a_mesh(p: Path, why: str) -> MeshFileError:
    return not_a_mesh(p, why)


def _check_vertices(p: Path, verts: np.ndarray, what: str, lines: np.ndarray | None = None) -> None:
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
    p: Path, verts: np.ndarray, dtype: torch.dtype, lines: np.ndarray | None = None, hint: str | None = None
) -> None:
    """Refuse coordinates that ``dtype`` cannot hold (they would become Inf), naming the first one and its line."""
    finfo_max = torch.finfo(dtype).max
    if verts.size == 0 or float(np.abs(verts).max()) <= finfo_max:
        return
    big = np.abs(verts).max(axis=1) > finfo_max
    i = int(np.nonzero(big)[0][0])
    where = f" line {int(lines[i])}:" if lines is not None else ""
    raise MeshFileError(
        f"path: mesh file '{p}'{where} vertex {i} has coordinates up to "
        f"{float(np.abs(verts).max()):.3g}, beyond the range of {dtype} (max {finfo_max:.3g}; "
        f"{int(big.sum())} such vertices); {hint or 'load it with dtype=torch.float64'}"
    )


def _text_lines(p: Path, data: bytes) -> list[bytes]:
    return text_lines(p, data)


def _parse_obj(p: Path, data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices, triangles and vertex lines of a Wavefront OBJ file (polygons refused, naming their line)."""
    d = parse_obj(p, data, uvs=False)
    sizes = d.face_sizes
    if sizes.size and (int(sizes.min()) != 3 or int(sizes.max()) != 3):
        j = int(np.nonzero(sizes != 3)[0][0])
        raise MeshFileError(
            f"path: '{p}' line {int(d.face_lines[j])} has a face with {int(sizes[j])} corners; expected triangles"
        )
    return d.verts, d.corners.reshape(-1, 3), d.vert_lines


def _parse_off(p: Path, data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an OFF file; the header's counts must match what the file holds."""
    check_text(p, data)
    fast = _parse_off_fast(data.removeprefix(b"\xef\xbb\xbf"))
    if fast is not None:
        return fast
    return _parse_off_slow(p, data)


def _parse_off_fast(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """Vectorised parse of a plain OFF (no comments, counts on their own line, uniform rows), else ``None``."""
    if b"#" in data or b"\r" in data or not data.startswith(b"OFF\n"):
        return None
    head = data.split(b"\n", 2)
    if len(head) < 3:
        return None
    try:
        counts = [int(t) for t in head[1].split()]
    except ValueError:
        return None
    if len(counts) not in (2, 3) or counts[0] < 0 or counts[1] < 0:
        return None
    nv, nf = counts[0], counts[1]
    body = head[2] if head[2].endswith(b"\n") else head[2] + b"\n"
    nl = np.flatnonzero(np.frombuffer(body, dtype=np.uint8) == 10)
    if nl.size != nv + nf or body.startswith(b"\n") or (np.diff(nl) == 1).any():
        return None  # truncated, more than declared or blank lines: the slow pass says which
    v_end = int(nl[nv - 1]) + 1 if nv else 0
    v_text, f_text = body[:v_end], body[v_end:]
    try:
        verts = np.fromstring(v_text, dtype=np.float64, sep=" ")
        faces = np.fromstring(f_text, dtype=np.int64, sep=" ")
    except ValueError:
        return None
    if verts.size != 3 * nv or faces.size != 4 * nf:
        return None  # colours, polygons or bad rows: the slow pass
    verts, faces = verts.reshape(-1, 3), faces.reshape(-1, 4)
    if (faces[:, 0] != 3).any() or not np.isfinite(verts).all():
        return None
    faces = faces[:, 1:]
    if faces.size and (faces.min() < 0 or faces.max() >= nv):
        return None
    return verts, np.ascontiguousarray(faces)


def _parse_off_slow(p: Path, data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """OFF line by line, naming the line of the first problem."""
    lines = [(n, ln.split(b"#", 1)[0].split()) for n, ln in enumerate(_text_lines(p, data), 1)]
    lines = [(n, t) for n, t in lines if t]
    if not lines or not re.fullmatch(rb"C?N?OFF", lines[0][1][0]):
        found = lines[0][1][0].decode("latin-1")[:20] if lines else "nothing"
        raise _not_a_mesh(p, f"an OFF file starts with 'OFF', found {found!r}")
    if b"BINARY" in lines[0][1][1:]:
        raise MeshFileError(f"path: '{p}' is a binary OFF file; only text OFF is supported")
    rest = lines[0][1][1:]
    body = lines[1:]
    if not rest:
        if not body:
            raise MeshFileError(f"path: '{p}' ends after its 'OFF' line (no vertex and face counts)")
        rest, body = body[0][1], body[1:]
    count_line = lines[0][0] if lines[0][1][1:] else lines[1][0]
    try:
        nv, nf = int(rest[0]), int(rest[1])
    except (ValueError, IndexError):
        raise MeshFileError(
            f"path: '{p}' line {count_line}: expected the counts 'vertices faces edges', found "
            f"{b' '.join(rest).decode('latin-1')!r}"
        ) from None
    if nv < 0 or nf < 0:
        raise MeshFileError(f"path: '{p}' line {count_line}: negative counts {nv} vertices, {nf} faces")
    if len(body) < nv + nf:
        held_v, held_f = min(len(body), nv), max(0, len(body) - nv)
        raise MeshFileError(
            f"path: '{p}' is truncated: its header (line {count_line}) declares {nv} vertices and {nf} faces, "
            f"the file holds {held_v} vertices and {held_f} faces"
        )
    if len(body) > nv + nf:
        extra = body[nv + nf][0]
        raise MeshFileError(
            f"path: '{p}' line {extra}: more lines than the header (line {count_line}) declares "
            f"({nv} vertices, {nf} faces)"
        )
    verts = np.empty((nv, 3))
    for i, (n, t) in enumerate(body[:nv]):
        if len(t) < 3:
            raise MeshFileError(f"path: '{p}' line {n}: vertex {i} has {len(t)} coordinate(s); expected 3")
        try:
            verts[i] = [float(x) for x in t[:3]]
        except ValueError:
            raise MeshFileError(f"path: '{p}' line {n}: vertex {i} coordinates are not numbers") from None
    _check_vertices(p, verts, "vertex", np.array([n for n, _ in body[:nv]]))
    faces = np.empty((nf, 3), dtype=np.int64)
    for j, (n, t) in enumerate(body[nv:]):
        try:
            corners = int(t[0])
            idx = [int(x) for x in t[1 : 1 + corners]]
        except ValueError:
            raise MeshFileError(f"path: '{p}' line {n}: face {j} is not a list of vertex indices") from None
        if corners != 3:
            raise MeshFileError(f"path: '{p}' line {n} has a face with {corners} corners; expected triangles")
        if len(idx) != 3:
            raise MeshFileError(f"path: '{p}' line {n}: face {j} declares 3 corners but lists {len(idx)}")
        if min(idx) < 0 or max(idx) >= nv:
            raise MeshFileError(
                f"path: '{p}' line {n}: face {j} has vertex indices {idx} outside [0, {nv - 1}] (OFF is 0-based)"
            )
        faces[j] = idx
    return verts, faces


def _utf8(data: bytes) -> bytes:
    """``data`` as UTF-8: unchanged when it is, else read as Latin-1 (trimesh then never guesses an encoding)."""
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1").encode("utf-8")
    return data


def _load_with_trimesh(p: Path, suffix: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """PLY, STL and GLB/GLTF through trimesh, with the declared element counts checked; ``(verts, faces, colors)``.

    ``colors`` are ``(V, 3)`` per-vertex colours in ``[0, 255]`` when the file has some, else ``None``.
    """
    import trimesh  # ~0.3 s to import: on use only, `import torchmeshmetric` never loads it

    declared: dict[str, int] = {}
    source: Any = os.fspath(p)
    if suffix == ".ply":
        data = p.read_bytes()
        if not data.startswith(b"ply"):
            raise _not_a_mesh(p, "a PLY file starts with 'ply'")
        end = data.find(b"end_header")
        if end < 0:
            raise MeshFileError(f"path: '{p}' has a PLY header without 'end_header'")
        header = data[:end]
        _text_lines(p, header)
        declared = {m[1].decode(): int(m[2]) for m in re.finditer(rb"element\s+(\w+)\s+(\d+)", header)}
        source = io.BytesIO(_utf8(header) + data[end:])
    elif suffix == ".stl":
        data = p.read_bytes()
        n = int.from_bytes(data[80:84], "little") if len(data) >= 84 else -1
        if len(data) != 84 + 50 * n:  # not binary STL: must be text
            if not data.lstrip().startswith(b"solid"):
                raise MeshFileError(
                    f"path: '{p}' is not a mesh file, or is truncated: a text STL starts with 'solid', and a binary "
                    f"STL whose header declares {max(n, 0)} triangles holds 84 + 50 * {max(n, 0)} bytes, this file "
                    f"{len(data)} bytes"
                )
            _text_lines(p, data)
            data = _utf8(data)
        else:
            declared = {"face": n}
        source = io.BytesIO(data)
    elif suffix == ".glb" and p.read_bytes()[:4] != b"glTF":
        raise _not_a_mesh(p, "a GLB file starts with 'glTF'")
    try:
        loaded = trimesh.load(source, file_type=suffix[1:], process=False, maintain_order=True)
    except Exception as err:  # trimesh raises many exception types on malformed input
        hint = ""
        if declared:
            counts = ", ".join(f"{n} {element}" for element, n in declared.items())
            hint = f"; its header declares {counts} elements: truncated or malformed?"
        raise MeshFileError(f"path: could not read mesh file '{p}' ({type(err).__name__}: {err}){hint}") from err
    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)] if loaded.geometry else []
        if not geoms:
            raise MeshFileError(f"path: mesh file '{p}' holds no triangle geometry")
        loaded = trimesh.util.concatenate(geoms) if len(geoms) > 1 else geoms[0]
    if not isinstance(loaded, trimesh.Trimesh):
        raise MeshFileError(f"path: '{p}' holds a {type(loaded).__name__}, not a triangle mesh")
    verts = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64)
    for element, held in (("vertex", verts.shape[0]), ("face", faces.shape[0])):
        if element in declared and declared[element] != held:
            what = "triangles" if element == "face" else "vertices"
            hint = " (truncated, or faces that are not triangles)" if element == "face" else " (truncated)"
            raise MeshFileError(
                f"path: '{p}' declares {declared[element]} {element} elements but holds {held} {what}{hint}"
            )
    visual = getattr(loaded, "visual", None)
    vc = getattr(visual, "vertex_colors", None)
    colors = None
    if vc is not None and getattr(visual, "kind", None) == "vertex":
        colors = np.asarray(vc, dtype=np.float64)[:, :3]
    return verts, faces, colors


_PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}


def _read_ply_fast(p: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
    """A plain PLY (a ``vertex`` then a triangle ``face`` element, nothing else) read with numpy, else ``None``.

    Binary (either byte order) or ASCII; vertex properties are scalars; the face element has one list property
    ``vertex_indices`` (or ``vertex_index``), every face a triangle. Anything else (other elements, polygons,
    truncation, trailing bytes) returns ``None`` and goes through trimesh, which then names the problem.
    Returns ``(verts, faces, colors)``, colours from ``uchar`` ``red green blue`` properties.
    """
    data = p.read_bytes()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        return None
    stop = data.find(b"\n", end)
    if stop < 0:
        return None
    header = data[:end].decode("latin-1").split("\n")
    body = data[stop + 1 :]
    fmt = None
    elements: list[tuple[str, int, list[tuple[str, ...]]]] = []
    for line in header[1:]:
        t = line.split()
        if not t or t[0] in ("comment", "obj_info"):
            continue
        if t[0] == "format" and len(t) >= 2:
            fmt = t[1]
        elif t[0] == "element" and len(t) == 3 and t[2].isdigit():
            elements.append((t[1], int(t[2]), []))
        elif t[0] == "property" and elements:
            elements[-1][2].append(tuple(t[1:]))
        else:
            return None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian") or [e[0] for e in elements] != [
        "vertex",
        "face",
    ]:
        return None
    (_, nv, vprops), (_, nf, fprops) = elements
    if any(len(pr) != 2 or pr[0] not in _PLY_TYPES for pr in vprops):
        return None
    names = [pr[1] for pr in vprops]
    if names[:3] != ["x", "y", "z"] and not {"x", "y", "z"} <= set(names):
        return None
    lists = [pr for pr in fprops if pr[0] == "list"]
    if (
        len(fprops) != 1
        or len(lists) != 1
        or len(lists[0]) != 4
        or lists[0][3] not in ("vertex_indices", "vertex_index")
    ):
        return None
    count_t, index_t = lists[0][1], lists[0][2]
    if count_t not in _PLY_TYPES or index_t not in _PLY_TYPES or _PLY_TYPES[index_t][0] == "f":
        return None
    if fmt == "ascii":
        try:
            flat = np.fromstring(body, dtype=np.float64, sep=" ")
        except ValueError:
            return None
        k = len(vprops)
        if flat.size != nv * k + nf * 4:
            return None
        table = flat[: nv * k].reshape(nv, k)
        # each value as its declared type holds it (a "float" property is float32, as trimesh and mmetric read it)
        cols = {n: table[:, i].astype(_PLY_TYPES[pr[0]]) for i, (pr, n) in enumerate(zip(vprops, names, strict=True))}
        fl = flat[nv * k :].reshape(nf, 4)
        if (fl[:, 0] != 3).any() or (fl[:, 1:] != np.round(fl[:, 1:])).any():
            return None
        faces = fl[:, 1:].astype(np.int64)
        int_colors = all(_PLY_TYPES[pr[0]] == "u1" for pr in vprops if pr[1] in ("red", "green", "blue"))
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        vdt = np.dtype([(n, order + _PLY_TYPES[t]) for t, n in vprops])
        idx_t = order + _PLY_TYPES[index_t]
        fdt = np.dtype([("n", order + _PLY_TYPES[count_t]), ("i0", idx_t), ("i1", idx_t), ("i2", idx_t)])
        if len(body) != nv * vdt.itemsize + nf * fdt.itemsize:
            return None  # polygons, truncation or trailing bytes: trimesh names which
        vtab = np.frombuffer(body, dtype=vdt, count=nv)
        ftab = np.frombuffer(body, dtype=fdt, count=nf, offset=nv * vdt.itemsize)
        if (ftab["n"] != 3).any():
            return None
        cols = {n: vtab[n] for n in names}
        if names[:3] == ["x", "y", "z"] and len({pr[0] for pr in vprops[:3]}) == 1:
            # x, y, z side by side: one strided view instead of three columns
            xyz = np.ndarray((nv, 3), dtype=vdt["x"], buffer=body, offset=0, strides=(vdt.itemsize, vdt["x"].itemsize))
            cols = {**cols, "xyz": xyz}
        faces = np.empty((nf, 3), dtype=np.int64)
        for k in range(3):  # one column at a time: three times faster than a (3,) subarray field
            faces[:, k] = ftab[f"i{k}"]
        int_colors = all(_PLY_TYPES[pr[0]] == "u1" for pr in vprops if pr[1] in ("red", "green", "blue"))
    if "xyz" in cols:
        verts = cols["xyz"].astype(np.float64)
    else:
        verts = np.stack([cols["x"], cols["y"], cols["z"]], axis=1).astype(np.float64)
    colors = None
    if {"red", "green", "blue"} <= set(names):
        if not int_colors:
            return None  # float colours: trimesh's conversion decides
        colors = np.stack([cols["red"], cols["green"], cols["blue"]], axis=1).astype(np.float64)
    return verts, faces, colors


def load_sequence(paths: PathsLike, *, dtype: torch.dtype = torch.float32) -> list[Mesh]:
    r"""Load the frames of a sequence in natural order (see :func:`list_frames`).

    Frames are read ahead by a background thread (:func:`iter_sequence`), so reading a file overlaps parsing the
    previous one.

    Args:
        paths: a directory, a glob pattern, a single file or a list of files.
        dtype: vertex dtype of the frames.

    Raises:
        MeshFileError: no frame found, or a frame cannot be read (the message names the file).

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> for n in (3, 1):
        ...     _ = (d / f"f{n}.obj").write_text(f"v 0 0 {n}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        >>> tuple(float(m.verts[0, 2]) for m in load_sequence(d))
        (1.0, 3.0)
    """
    with iter_sequence(paths, dtype=dtype) as frames:
        return list(frames)


def iter_sequence(paths: PathsLike, *, dtype: torch.dtype = torch.float32, ahead: int = 2) -> Prefetcher[Mesh]:
    r"""The frames of a sequence, in natural order, loaded ``ahead`` frames in advance by a background thread.

    Use it where frames are processed one at a time: frame ``k + 1`` is read and parsed while frame ``k`` is
    being used, and at most ``ahead + 1`` frames are in memory. Same files, order and errors as
    :func:`load_sequence`.

    Args:
        paths: a directory, a glob pattern, a single file or a list of files.
        dtype: vertex dtype of the frames.
        ahead: frames loaded in advance (>= 1).

    Returns:
        A :class:`Prefetcher` (an iterator and a context manager).

    Raises:
        MeshFileError: no frame found (at once), or a frame cannot be read (when that frame is reached).

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> for n in (2, 1):
        ...     _ = (d / f"f{n}.obj").write_text(f"v 0 0 {n}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        >>> with iter_sequence(d) as frames:
        ...     tuple(m.num_verts for m in frames)
        (3, 3)
    """
    return prefetch_frames(list_frames(paths), load=lambda p: load_mesh(p, dtype=dtype), ahead=ahead)


T = TypeVar("T")


class Prefetcher(Iterator[T]):
    """Items ``load(path)`` produced by a background thread, ``ahead`` items in advance, yielded in order.

    An exception raised by ``load`` is re-raised by :meth:`__next__` at the item that failed (the items before it
    are yielded first), and nothing after it is loaded. :meth:`close` (also on leaving a ``with`` block, on
    garbage collection, and after the last item) stops the thread, which finishes at most the item it is loading;
    an early ``break`` or a ``KeyboardInterrupt`` in the consumer therefore never leaves work running.

    Args:
        paths: the items' paths, in order.
        load: called on each path in the background thread.
        ahead: items loaded in advance (>= 1).

    Example:
        >>> with Prefetcher(["a", "b", "c"], load=str.upper, ahead=2) as items:
        ...     list(items)
        ['A', 'B', 'C']
    """

    def __init__(self, paths: Iterable[Any], load: Callable[[Any], T], ahead: int = 2) -> None:
        if isinstance(ahead, bool) or not isinstance(ahead, int) or ahead < 1:
            raise ValueError(f"ahead: expected an integer >= 1, found {ahead!r}")
        if not callable(load):
            raise TypeError(f"load: expected a callable, found {type(load).__name__}")
        self._paths = list(paths)
        self._load = load
        self._queue: queue.Queue[tuple[bool, Any]] = queue.Queue(maxsize=ahead)
        self._stop = threading.Event()
        self._done = False
        self._thread = threading.Thread(target=self._work, name="torchmeshmetric-prefetch", daemon=True)
        self._thread.start()

    def _put(self, item: tuple[bool, Any]) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _work(self) -> None:
        for path in self._paths:
            if self._stop.is_set():
                return
            try:
                item = (True, self._load(path))
            except BaseException as exc:  # handed to the consumer, raised there at this item
                self._put((False, exc))
                return
            if not self._put(item):
                return
        self._put((True, _END))

    def __iter__(self) -> Prefetcher[T]:
        return self

    def __next__(self) -> T:
        if self._done:
            raise StopIteration
        try:
            while True:
                try:
                    ok, value = self._queue.get(timeout=0.1)
                    break
                except queue.Empty:
                    if not self._thread.is_alive() and self._queue.empty():
                        raise RuntimeError("prefetch: the loading thread ended without a result") from None
        except BaseException:
            self.close()
            raise
        if not ok:
            self.close()
            raise value
        if value is _END:
            self.close()
            raise StopIteration
        return cast(T, value)

    def close(self) -> None:
        """Stop the background thread and drop what it loaded ahead (idempotent)."""
        self._done = True
        self._stop.set()
        while True:
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join()

    def __enter__(self) -> Prefetcher[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        if getattr(self, "_thread", None) is not None:
            self._stop.set()


_END = object()


@overload
def prefetch_frames(paths: PathsLike, *, load: None = None, ahead: int = 2) -> Prefetcher[Mesh]: ...


@overload
def prefetch_frames(paths: PathsLike, *, load: Callable[[Path], T], ahead: int = 2) -> Prefetcher[T]: ...


def prefetch_frames(paths: PathsLike, *, load: Callable[[Path], Any] | None = None, ahead: int = 2) -> Prefetcher[Any]:
    r"""Load frames in a background thread, ``ahead`` in advance, and yield them in order (I/O overlaps work).

    Args:
        paths: a directory, a glob pattern, a single file or a list of files (see :func:`list_frames`).
        load: what to call on each path (default :func:`load_mesh`), e.g.
            :func:`~torchmeshmetric.mpeg.load_textured_mesh`.
        ahead: frames loaded in advance (>= 1); at most ``ahead + 1`` frames are in memory.

    Returns:
        A :class:`Prefetcher`: iterate it, preferably in a ``with`` block (it is closed on leaving it, on an early
        ``break`` once collected, and after the last frame). An error loading frame ``k`` is raised when frame
        ``k`` is reached.

    Raises:
        MeshFileError: no frame found (at once).
        ValueError: ``ahead < 1``.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> for n in (10, 2):
        ...     _ = (d / f"f{n}.obj").write_text(f"v 0 0 {n}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        >>> with prefetch_frames(d, ahead=1) as frames:
        ...     tuple(float(m.verts[0, 2]) for m in frames)
        (2.0, 10.0)
    """
    files = list_frames(paths)
    return Prefetcher(files, load if load is not None else load_mesh, ahead)


def save_mesh(mesh: Mesh, path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Write a mesh atomically (temporary file in the same directory, then ``os.replace``), with normal permissions.

    Inside :func:`~torchmeshmetric._atomic.atomic_file_set` the file joins the set (all files or none appear).

    The format follows the suffix (OBJ, PLY, OFF, STL, GLB). Vertices are written in their order, unmerged.

    Args:
        mesh: the mesh to write.
        path: the destination file; its directory must exist.
        overwrite: replace an existing file (default ``False``: refuse).

    Returns:
        The written path.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is false.
        MeshFileError: unsupported suffix, missing directory, or an empty mesh.

    Example:
        >>> import tempfile, pathlib, torch
        >>> m = Mesh(torch.tensor([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> p = save_mesh(m, pathlib.Path(tempfile.mkdtemp()) / "tri.ply")
        >>> load_mesh(p).num_faces
        1
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES or suffix == ".gltf":
        raise MeshFileError(f"path: cannot write '{p}': unsupported suffix '{p.suffix}' (use .obj/.ply/.off/.stl/.glb)")
    if not p.parent.is_dir():
        raise MeshFileError(str(missing_folder_error(p.parent)))
    if p.exists() and not overwrite:
        raise FileExistsError(f"path: '{p}' exists; pass overwrite=True to replace it")
    if not isinstance(mesh, Mesh):
        raise TypeError(f"mesh: expected a Mesh, found {type(mesh).__name__}")
    if mesh.num_faces == 0:
        raise EmptyInputError(f"mesh: cannot write '{p}': the mesh has no faces")
    if mesh.faces.shape[1] != 3:
        raise ShapeError(f"mesh.faces: expected shape (F, 3), found {tuple(mesh.faces.shape)}")
    if suffix == ".obj":
        data = _obj_bytes(mesh)
    else:
        exported = mesh.to_trimesh().export(file_type=suffix[1:])
        data = exported.encode() if isinstance(exported, str) else bytes(exported)
    atomic_write(p, data, overwrite=overwrite)
    return p


def _obj_bytes(mesh: Mesh) -> bytes:
    """Minimal OBJ writer (vertices at full float64 precision via ``repr``-exact ``%.17g``, 1-based faces)."""
    v = mesh.verts.detach().cpu().double().numpy()
    f = mesh.faces.cpu().numpy() + 1
    lines = ["v " + " ".join(f"{x:.17g}" for x in row) for row in v]
    lines += [f"f {a} {b} {c}" for a, b, c in f]
    return ("\n".join(lines) + "\n").encode()
