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
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from torchmeshmetric._atomic import atomic_write, missing_folder_error
from torchmeshmetric._checks import EmptyInputError, ShapeError
from torchmeshmetric.structures import Mesh

__all__ = [
    "MESH_SUFFIXES",
    "MeshFileError",
    "PathsLike",
    "list_frames",
    "load_mesh",
    "load_sequence",
    "natural_key",
    "save_mesh",
]

MESH_SUFFIXES: tuple[str, ...] = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")
"""File suffixes recognised as mesh frames (case-insensitive)."""

PathsLike = str | os.PathLike | Sequence[str | os.PathLike]
"""A directory, a glob pattern, a single file, or a list of files."""


class MeshFileError(ValueError):
    """A mesh file is missing, unreadable, corrupt, empty or not made of triangles (the message names the file)."""


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
    p = Path(path)
    if not p.is_file():
        raise MeshFileError(f"path: mesh file '{p}' does not exist")
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise MeshFileError(f"path: '{p}' has unsupported suffix '{p.suffix}' (expected one of {MESH_SUFFIXES})")
    if p.stat().st_size == 0:
        raise MeshFileError(f"path: mesh file '{p}' is empty (0 bytes)")
    if suffix in (".obj", ".off"):
        data = p.read_bytes()
        verts, faces = (_parse_obj if suffix == ".obj" else _parse_off)(p, data)
    else:
        verts, faces = _load_with_trimesh(p, suffix)
    if faces.ndim != 2 or faces.shape[0] == 0:
        raise MeshFileError(f"path: mesh file '{p}' has no faces ({verts.shape[0]} vertices)")
    if faces.shape[1] != 3:
        raise MeshFileError(f"path: mesh file '{p}' has {faces.shape[1]}-sided faces; expected triangles")
    if verts.ndim != 2 or verts.shape[1] != 3:
        raise MeshFileError(f"path: mesh file '{p}' has vertices of shape {verts.shape}; expected (V, 3)")
    _check_vertices(p, verts, "vertex")
    if faces.min() < 0 or faces.max() >= verts.shape[0]:
        bad = int(np.nonzero((faces < 0).any(1) | (faces >= verts.shape[0]).any(1))[0][0])
        raise MeshFileError(
            f"path: mesh file '{p}' face {bad} has vertex indices {faces[bad].tolist()} outside "
            f"[0, {verts.shape[0] - 1}]"
        )
    out = torch.from_numpy(verts).to(dtype)
    if not bool(torch.isfinite(out).all()):
        big = float(np.abs(verts).max())
        raise MeshFileError(
            f"path: mesh file '{p}' has coordinates up to {big:.3g}, beyond the range of {dtype} "
            f"(max {torch.finfo(dtype).max:.3g}); load it with dtype=torch.float64"
        )
    return Mesh(out, torch.from_numpy(faces), validate=False)


def _not_a_mesh(p: Path, why: str) -> MeshFileError:
    return MeshFileError(f"path: '{p}' is not a mesh file ({why})")


def _check_vertices(p: Path, verts: np.ndarray, what: str, lines: np.ndarray | None = None) -> None:
    """Every coordinate finite; the message names the first bad vertex (and its line when known)."""
    bad = ~np.isfinite(verts).all(axis=1)
    if bad.any():
        i = int(np.nonzero(bad)[0][0])
        where = f" (line {int(lines[i])})" if lines is not None else ""
        raise MeshFileError(
            f"path: mesh file '{p}' {what} {i}{where} has non-finite coordinates {verts[i].tolist()} "
            f"({int(bad.sum())} such vertices)"
        )


def _text_lines(p: Path, data: bytes) -> list[bytes]:
    """Lines of a text mesh format; binary data (NUL or other control bytes) is refused as not a mesh file."""
    control = re.search(rb"[\x00-\x08\x0e-\x1f\x7f]", data)
    if control is not None:
        line = data.count(b"\n", 0, control.start()) + 1
        raise _not_a_mesh(p, f"binary data at line {line}, byte {control.start()}")
    return data.removeprefix(b"\xef\xbb\xbf").splitlines()  # a UTF-8 byte-order mark is no statement


_OBJ_KEYWORDS = frozenset(
    b"v vt vn vp f l p o g s mg mtllib usemtl cstype deg bmat step curv curv2 surf parm trim hole scrv sp end con "
    b"bevel c_interp d_interp lod shadow_obj trace_obj ctech stech call csh maplib usemap".split()
)


def _parse_obj(p: Path, data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of a Wavefront OBJ file, in file order, with line-level errors.

    OBJ indices are 1-based; a negative index ``-k`` is the ``k``-th vertex counted back from the last one defined
    before its line (so ``f -3 -2 -1`` is the last three vertices). ``v x y z [w]`` and ``v x y z r g b [a]``
    (vertex colours) are accepted; texture and normal indices (``f 1/1/1 ...``) are ignored.
    """
    lines = _text_lines(p, data)
    fast = _parse_obj_fast(data.removeprefix(b"\xef\xbb\xbf"))
    if fast is not None:
        return fast
    # The slow path: one statement at a time, to name the line of the first problem.
    verts: list[list[float]] = []
    vert_lines: list[int] = []
    faces: list[list[int]] = []
    pending = b""
    start = 0
    statements = 0
    for lineno, raw in enumerate(lines, 1):
        line = pending + raw
        if line.rstrip().endswith(b"\\"):  # line continuation
            pending = line.rstrip()[:-1] + b" "
            start = start or lineno
            continue
        at, pending, start = start or lineno, b"", 0
        tokens = line.split(b"#", 1)[0].split()
        if not tokens:
            continue
        key = tokens[0]
        if key not in _OBJ_KEYWORDS:
            raise _not_a_mesh(p, f"line {at} starts with {key.decode('latin-1')!r}, not an OBJ statement")
        statements += 1
        if key == b"v":
            n = len(tokens) - 1
            if n not in (3, 4, 6, 7):
                raise MeshFileError(
                    f"path: '{p}' line {at}: vertex {len(verts)} has {n} coordinate(s); expected 'v x y z' "
                    "(optionally w, or r g b [a])"
                )
            try:
                verts.append([float(t) for t in tokens[1:4]])
            except ValueError:
                raise MeshFileError(
                    f"path: '{p}' line {at}: vertex coordinates {b' '.join(tokens[1:4]).decode('latin-1')!r} "
                    "are not numbers"
                ) from None
            vert_lines.append(at)
        elif key == b"f":
            n = len(tokens) - 1
            if n != 3:
                raise MeshFileError(f"path: '{p}' line {at} has a face with {n} corners; expected triangles")
            face = []
            for t in tokens[1:]:
                try:
                    idx = int(t.split(b"/", 1)[0])
                except ValueError:
                    raise MeshFileError(
                        f"path: '{p}' line {at}: face corner {t.decode('latin-1')!r} is not a vertex index"
                    ) from None
                if idx == 0:
                    raise MeshFileError(
                        f"path: '{p}' line {at}: face index 0 is invalid (OBJ indices start at 1; negative ones "
                        "count back from the last vertex)"
                    )
                if idx < 0:
                    if -idx > len(verts):
                        raise MeshFileError(
                            f"path: '{p}' line {at}: face index {idx} counts back past the first vertex "
                            f"({len(verts)} vertices defined before this line)"
                        )
                    idx = len(verts) + idx + 1
                face.append(idx - 1)
            faces.append(face)
    if statements == 0:
        raise _not_a_mesh(p, "no OBJ statement (v, f, ...) found")
    v = np.array(verts, dtype=np.float64).reshape(-1, 3)
    f = np.array(faces, dtype=np.int64).reshape(-1, 3)
    _check_vertices(p, v, "vertex", np.array(vert_lines))
    if f.size and f.max() >= len(v):
        row = int(np.nonzero((f >= len(v)).any(1))[0][0])
        raise MeshFileError(
            f"path: '{p}' face {row}: vertex index {int(f[row].max()) + 1} is out of range (the file has "
            f"{len(v)} vertices)"
        )
    return v, f


_OBJ_V3 = re.compile(rb"^v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)[ \t]*\r?$", re.M)
_OBJ_F3 = re.compile(rb"^f[ \t]+([^\s/]+)\S*[ \t]+([^\s/]+)\S*[ \t]+([^\s/]+)\S*[ \t]*\r?$", re.M)


def _parse_obj_fast(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """Vectorised parse of a plain OBJ, or ``None`` whenever anything is unusual or wrong.

    Plain: ``v x y z`` and ``f a b c`` (``a/t/n`` corners) lines with positive indices, no line continuation and
    no comment after a statement. The slow path parses anything else, and names the line of a problem.
    """
    if b"\\" in data or re.search(rb"^[ \t]*[vf][ \t][^#\n]*#", data, re.M):
        return None
    keys = set(re.findall(rb"^[ \t]*([^\s#]+)", data, re.M))
    if not keys <= _OBJ_KEYWORDS:
        return None
    v_rows = _OBJ_V3.findall(data)
    f_rows = _OBJ_F3.findall(data)
    if not v_rows:
        return None
    if len(v_rows) != len(re.findall(rb"^v[ \t]", data, re.M)) or len(f_rows) != len(
        re.findall(rb"^f[ \t]", data, re.M)
    ):
        return None
    try:
        verts = np.fromiter(map(float, (x for r in v_rows for x in r)), np.float64, 3 * len(v_rows))
        faces = np.fromiter(map(int, (x for r in f_rows for x in r)), np.int64, 3 * len(f_rows)) - 1
    except ValueError:
        return None
    if not np.isfinite(verts).all() or (faces.size and (faces.min() < 0 or faces.max() >= len(v_rows))):
        return None
    return verts.reshape(-1, 3), faces.reshape(-1, 3)


def _parse_off(p: Path, data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an OFF file; the header's counts must match what the file holds."""
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
    fast = _parse_off_fast(body, nv)
    if fast is not None:
        return fast
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


def _parse_off_fast(body: list[tuple[int, list[bytes]]], nv: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Vectorised parse of OFF vertex and triangle lines, or ``None`` when anything is unusual or wrong."""
    v_rows = [t[:3] for _, t in body[:nv]]
    f_rows = [t for _, t in body[nv:]]
    if any(len(r) != 3 for r in v_rows) or any(len(r) != 4 or r[0] != b"3" for r in f_rows):
        return None
    try:
        verts = np.array(v_rows, dtype=np.bytes_).astype(np.float64).reshape(-1, 3)
        faces = np.array([r[1:] for r in f_rows], dtype=np.bytes_).astype(np.int64).reshape(-1, 3)
    except ValueError:
        return None
    if not np.isfinite(verts).all() or (faces.size and (faces.min() < 0 or faces.max() >= nv)):
        return None
    return verts, faces


def _utf8(data: bytes) -> bytes:
    """``data`` as UTF-8: unchanged when it is, else read as Latin-1 (trimesh then never guesses an encoding)."""
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1").encode("utf-8")
    return data


def _load_with_trimesh(p: Path, suffix: str) -> tuple[np.ndarray, np.ndarray]:
    """PLY, STL and GLB/GLTF through trimesh, with the declared element counts checked."""
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
    return verts, faces


def load_sequence(paths: PathsLike, *, dtype: torch.dtype = torch.float32) -> list[Mesh]:
    r"""Load the frames of a sequence in natural order (see :func:`list_frames`).

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
    return [load_mesh(p, dtype=dtype) for p in list_frames(paths)]


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
