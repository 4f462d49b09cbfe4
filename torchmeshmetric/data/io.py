"""One mesh file in and out: load (every format through its one reader, checked), save atomically.

OBJ (:mod:`~torchmeshmetric.data.obj`), OFF (:mod:`~torchmeshmetric.data.off`) and plain PLY
(:mod:`~torchmeshmetric.data.ply`) are parsed by the library (line-level errors); other PLYs, STL and GLB/GLTF are read
with trimesh and ``process=False`` (:mod:`~torchmeshmetric.data.trimesh_formats`). Either way vertex order and
duplicate vertices survive exactly as stored (a registration or evaluation refers to vertices by index), and what a
file holds is checked against what it declares (see :func:`load_mesh`). A multi-mesh scene is concatenated.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import torch

from torchmeshmetric._atomic import atomic_write, missing_folder_error
from torchmeshmetric._checks import EmptyInputError, ShapeError, check_flag, check_float_dtype
from torchmeshmetric.data.mesh_file import (
    MeshFileError,
    check_dtype_range,
    check_mesh,
    existing_mesh_file,
    to_tensor,
)
from torchmeshmetric.data.obj import obj_bytes, read_obj_triangles
from torchmeshmetric.data.off import off_bytes, parse_off
from torchmeshmetric.data.ply import ply_bytes, read_plain_ply
from torchmeshmetric.data.trimesh_formats import read_with_trimesh
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = ["WRITABLE_MESH_SUFFIXES", "load_mesh", "read_mesh_arrays", "save_mesh"]

WRITABLE_MESH_SUFFIXES: tuple[str, ...] = (".obj", ".ply", ".off", ".stl", ".glb")
"""Suffixes :func:`save_mesh` writes (case-insensitive); ``.gltf`` is read only (written, it is several files)."""


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
        dtype: vertex dtype of the result, ``torch.float32`` (default) or ``torch.float64``.

    Returns:
        The mesh on the CPU.

    Raises:
        MeshFileError: the file is missing, of an unknown format, not a mesh file, corrupt or truncated, empty,
            has non-triangle faces, invalid face indices or non-finite coordinates (the message names the file and,
            where there is one, the line or element).
        DTypeError: ``dtype`` is neither torch.float32 nor torch.float64 (checked before the file is read).

    Example:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "tri.obj"
        >>> _ = p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -1\n")
        >>> load_mesh(p)
        Mesh(num_verts=3, num_faces=1, dtype=torch.float32, device=cpu)
    """
    check_float_dtype(dtype)  # validate=False below: nothing else would refuse a float16 or complex mesh
    p = existing_mesh_file(path)
    verts, faces, _, lines = _read_file(p)
    check_mesh(p, verts, faces, lines)
    check_dtype_range(p, verts, dtype, lines)
    return Mesh(to_tensor(verts, dtype), torch.from_numpy(faces), validate=False)


def _read_file(p: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """``(verts, faces, colors or None, vertex lines or None)`` of an existing mesh file, through its one reader."""
    suffix = p.suffix.lower()
    if suffix == ".obj":
        verts, faces, lines = read_obj_triangles(p, p.read_bytes())
        return verts, faces, None, lines
    if suffix == ".off":
        return (*parse_off(p, p.read_bytes()), None, None)
    plain = read_plain_ply(p) if suffix == ".ply" else None
    verts, faces, colors = plain[:3] if plain is not None else read_with_trimesh(p, suffix)
    return verts, faces, colors, None


def read_mesh_arrays(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    r"""``(verts, faces, colors)`` of a mesh file through its format's one reader, every check of :func:`load_mesh`.

    The same reader and checks as :func:`load_mesh` (which needs no colours); ``colors`` are ``(V, 3)`` per-vertex
    colours in ``[0, 255]`` from a PLY's ``red green blue`` (or trimesh's reading of other formats), else ``None``.
    OBJ colours are read by :func:`~torchmeshmetric.mpeg.load_textured_mesh`.

    Args:
        path: an OBJ, OFF, PLY, STL, GLB or glTF file.

    Returns:
        ``(verts, faces, colors)``: ``(V, 3)`` float64 vertices, ``(F, 3)`` int64 faces, and ``(V, 3)`` colours or
        ``None``, as stored (vertex order and duplicates kept).

    Raises:
        MeshFileError: the file is missing, empty, not a mesh, truncated, or holds a bad value (named with its line;
            see ``docs/bad-input.md``).

    Example:
        >>> import tempfile, pathlib
        >>> with tempfile.TemporaryDirectory() as d:
        ...     path = pathlib.Path(d, "t.obj")
        ...     _ = path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        ...     v, f, c = read_mesh_arrays(path)
        >>> v.shape, f.tolist(), c
        ((3, 3), [[0, 1, 2]], None)
    """
    p = existing_mesh_file(path)
    verts, faces, colors, lines = _read_file(p)
    check_mesh(p, verts, faces, lines)
    return verts, faces, colors


def save_mesh(mesh: MeshLike, path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Write a mesh atomically (temporary file in the same directory, then ``os.replace``), with normal permissions.

    Inside :func:`~torchmeshmetric._atomic.atomic_file_set` the file joins the set (all files or none appear).

    The format follows the suffix (OBJ, PLY, OFF, STL, GLB). OBJ, PLY, OFF and GLB write the vertices in their
    order, unmerged, and the faces as indices into them. STL cannot keep a vertex list: it stores each triangle's
    three corners, so a mesh read back from STL is a triangle soup (3 vertices per face, each shared vertex once per
    face corner), whose vertex statistics differ (the simplifiers weld its coincident corners themselves; for the
    statistics, weld it with trimesh's ``merge_vertices()`` or store frames in another format). OBJ, OFF and PLY
    read back bit for bit in the mesh's dtype (OFF: each coordinate's shortest decimal for that dtype; PLY: binary,
    ``double`` properties for a float64 mesh, ``float`` otherwise); STL and GLB store float32, bit for bit for a
    float32 mesh only (a float64 coordinate beyond float32's range is refused, never written as inf).

    Args:
        mesh: the mesh to write: a :class:`~torchmeshmetric.structures.Mesh`, a ``(verts, faces)`` tuple of tensors
            or arrays, or a ``trimesh.Trimesh`` (:func:`~torchmeshmetric.structures.as_mesh`), as every function of
            the library that takes a mesh.
        path: the destination file; its directory must exist.
        overwrite: replace an existing file (default ``False``: refuse).

    Returns:
        The written path.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is false.
        MeshFileError: unsupported suffix, missing directory, or (STL, GLB) a coordinate beyond float32's range.
        EmptyInputError: a mesh without faces.
        TypeError: ``mesh`` is none of the forms above (and the errors of :func:`~torchmeshmetric.structures.as_mesh`
            for a malformed tuple).

    Example:
        >>> import tempfile, pathlib, torch
        >>> m = Mesh(torch.tensor([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> p = save_mesh(m, pathlib.Path(tempfile.mkdtemp()) / "tri.ply")
        >>> load_mesh(p).num_faces
        1
    """
    overwrite = check_flag(overwrite, "overwrite")
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in WRITABLE_MESH_SUFFIXES:
        use = "/".join(WRITABLE_MESH_SUFFIXES)
        raise MeshFileError(f"path: cannot write '{p}': unsupported suffix '{p.suffix}' (use {use})")
    if not p.parent.is_dir():
        raise MeshFileError(str(missing_folder_error(p.parent)))
    if p.exists() and not overwrite:
        raise FileExistsError(f"path: '{p}' exists; pass overwrite=True to replace it")
    # A (verts, faces) tuple was refused, though the library's every other function that takes a mesh takes one
    # (found by review); a Mesh comes back as it is
    mesh = as_mesh(mesh, name="mesh")
    if mesh.num_faces == 0:
        raise EmptyInputError(f"mesh: cannot write '{p}': the mesh has no faces")
    if mesh.faces.shape[1] != 3:
        raise ShapeError(f"mesh.faces: expected shape (F, 3), found {tuple(mesh.faces.shape)}")
    if suffix == ".obj":
        data = obj_bytes(mesh)
    elif suffix == ".off":
        data = off_bytes(mesh)  # trimesh's OFF has 10 decimals: 3e-11 became 0
    elif suffix == ".ply":  # trimesh's PLY is float32 whatever the mesh: a float64 mesh lost its low bits
        v = mesh.verts.detach().cpu()
        data = ply_bytes(v.numpy() if v.dtype == torch.float64 else v.float().numpy(), mesh.faces.cpu().numpy())
    else:
        # STL and GLB store float32: a float64 coordinate beyond its range was written as inf (found by review)
        kind = suffix[1:].upper()
        check_dtype_range(
            p,
            mesh.verts.detach().cpu().double().numpy(),
            torch.float32,
            hint=f"cannot write it as {kind}, which stores float32: save as .ply, .obj or .off (float64), or scale it",
        )
        exported = mesh.to_trimesh().export(file_type=suffix[1:])
        data = exported.encode() if isinstance(exported, str) else bytes(exported)
    atomic_write(p, data, overwrite=overwrite)
    return p
