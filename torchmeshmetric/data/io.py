"""Mesh and sequence I/O: load frames in natural order, save atomically.

Files are read with trimesh and ``process=False``, so vertex order and duplicate vertices survive exactly as stored
(a registration or evaluation refers to vertices by index). Supported: OBJ, PLY, OFF, STL, GLB/GLTF (a scene is
concatenated into one mesh).
"""

from __future__ import annotations

import glob as _glob
import os
import re
from collections.abc import Sequence
from pathlib import Path

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

    Args:
        path: an OBJ, PLY, OFF, STL or GLB/GLTF file. A multi-mesh scene is concatenated.
        dtype: vertex dtype of the result (default ``float32``).

    Returns:
        The mesh on the CPU.

    Raises:
        MeshFileError: the file is missing, of an unknown format, corrupt, empty, or has non-triangle faces.

    Example:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "tri.obj"
        >>> _ = p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        >>> load_mesh(p)
        Mesh(num_verts=3, num_faces=1, dtype=torch.float32, device=cpu)
    """
    import trimesh

    p = Path(path)
    if not p.is_file():
        raise MeshFileError(f"path: mesh file '{p}' does not exist")
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise MeshFileError(f"path: '{p}' has unsupported suffix '{p.suffix}' (expected one of {MESH_SUFFIXES})")
    if p.stat().st_size == 0:
        raise MeshFileError(f"path: mesh file '{p}' is empty (0 bytes)")
    if suffix == ".obj":
        _check_obj_triangles(p)
    try:
        loaded = trimesh.load(os.fspath(p), process=False, maintain_order=True)
    except Exception as err:  # trimesh raises many exception types on malformed input
        raise MeshFileError(f"path: could not read mesh file '{p}' ({type(err).__name__}: {err})") from err
    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)] if loaded.geometry else []
        if not geoms:
            raise MeshFileError(f"path: mesh file '{p}' holds no triangle geometry")
        loaded = trimesh.util.concatenate(geoms) if len(geoms) > 1 else geoms[0]
    if not isinstance(loaded, trimesh.Trimesh):
        raise MeshFileError(f"path: '{p}' holds a {type(loaded).__name__}, not a triangle mesh")
    verts = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64)
    if faces.ndim != 2 or faces.shape[0] == 0:
        raise MeshFileError(f"path: mesh file '{p}' has no faces ({verts.shape[0]} vertices)")
    if faces.shape[1] != 3:
        raise MeshFileError(f"path: mesh file '{p}' has {faces.shape[1]}-sided faces; expected triangles")
    if not np.isfinite(verts).all():
        raise MeshFileError(f"path: mesh file '{p}' has non-finite vertex coordinates")
    if faces.min() < 0 or faces.max() >= verts.shape[0]:
        raise MeshFileError(f"path: mesh file '{p}' has face indices outside [0, {verts.shape[0]})")
    return Mesh(torch.from_numpy(verts).to(dtype), torch.from_numpy(faces), validate=False)


def _check_obj_triangles(p: Path) -> None:
    """Refuse OBJ polygons (trimesh would triangulate them silently): a frame must be made of triangles."""
    with p.open("rb") as fh:
        for lineno, raw in enumerate(fh, 1):
            if raw.startswith(b"f ") or raw.startswith(b"f\t"):
                n = len(raw.split()) - 1
                if n != 3:
                    raise MeshFileError(f"path: '{p}' line {lineno} has a face with {n} corners; expected triangles")


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
