"""Helpers shared by the registration modules (input validation, masks, normals, normalisation)."""

from __future__ import annotations

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, check_same_device
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh


def validate_pair(source: MeshLike, target: MeshLike) -> tuple[Mesh, Mesh]:
    """Validate both meshes (typed errors), require one device and faces with positive total area.

    Vertices are promoted to a common floating dtype (at least float32).
    """
    src = as_mesh(source, name="source")
    tgt = as_mesh(target, name="target")
    check_same_device({"source": src.verts, "target": tgt.verts})
    for name, m in (("source", src), ("target", tgt)):
        if m.num_verts == 0:
            raise EmptyInputError(f"{name}: expected at least one vertex, found an empty mesh")
        if m.num_faces == 0:
            raise EmptyInputError(f"{name}: expected at least one face, found none")
        if not bool(m.face_areas().sum() > 0):
            raise EmptyInputError(f"{name}: expected a surface with positive area, found only zero-area faces")
    dtype = torch.promote_types(torch.promote_types(src.dtype, tgt.dtype), torch.float32)
    return src.to(dtype=dtype), tgt.to(dtype=dtype)


def normalisation(mesh: Mesh) -> tuple[Tensor, Tensor]:
    """``(center (3,), diagonal (0-dim))`` of the bounding box of the surface vertices: the registration's frame.

    The non-rigid registration works on ``(x - center) / diagonal`` so that its thresholds are fractions of the
    target's diagonal.
    """
    ref = mesh.verts[referenced_mask(mesh)]
    return 0.5 * (ref.amin(0) + ref.amax(0)), (ref.amax(0) - ref.amin(0)).norm()


def referenced_mask(mesh: Mesh) -> Tensor:
    """``(V,)`` bool: vertices referenced by at least one face of positive area (the surface's vertices)."""
    used = torch.zeros(mesh.num_verts, dtype=torch.bool, device=mesh.device)
    good = mesh.face_areas() > 0
    used[mesh.faces[good].reshape(-1)] = True
    return used


def _unit(x: Tensor) -> Tensor:
    norm = x.norm(dim=-1, keepdim=True)
    return torch.where(norm > 0, x / torch.where(norm > 0, norm, torch.ones_like(norm)), torch.zeros_like(x))


def _face_cross(verts: Tensor, faces: Tensor) -> Tensor:
    tri = verts[faces]
    return torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1)  # 2 * area * unit normal


def _vertex_sum(verts: Tensor, faces: Tensor, n: Tensor) -> Tensor:
    acc = torch.zeros_like(verts).index_add(0, faces[:, 0], n).index_add(0, faces[:, 1], n)
    return acc.index_add(0, faces[:, 2], n)


def face_unit_normals(verts: Tensor, faces: Tensor) -> Tensor:
    """``(F, 3)`` unit face normals; exactly zero for zero-area faces (they have no normal)."""
    return _unit(_face_cross(verts, faces))


def vertex_unit_normals(verts: Tensor, faces: Tensor) -> Tensor:
    """``(V, 3)`` area-weighted vertex normals, unit length; zero where no face of positive area touches."""
    return _unit(_vertex_sum(verts, faces, _face_cross(verts, faces)))


def unit_normals(verts: Tensor, faces: Tensor) -> tuple[Tensor, Tensor]:
    """``(face_unit_normals, vertex_unit_normals)`` from one pass of face cross products (same values)."""
    n = _face_cross(verts, faces)
    return _unit(n), _unit(_vertex_sum(verts, faces, n))
