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


def referenced_mask(mesh: Mesh) -> Tensor:
    """``(V,)`` bool: vertices referenced by at least one face of positive area (the surface's vertices)."""
    used = torch.zeros(mesh.num_verts, dtype=torch.bool, device=mesh.device)
    good = mesh.face_areas() > 0
    used[mesh.faces[good].reshape(-1)] = True
    return used


def face_unit_normals(verts: Tensor, faces: Tensor) -> Tensor:
    """``(F, 3)`` unit face normals; exactly zero for zero-area faces (they have no normal)."""
    tri = verts[faces]
    n = torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1)
    norm = n.norm(dim=-1, keepdim=True)
    return torch.where(norm > 0, n / torch.where(norm > 0, norm, torch.ones_like(norm)), torch.zeros_like(n))


def vertex_unit_normals(verts: Tensor, faces: Tensor) -> Tensor:
    """``(V, 3)`` area-weighted vertex normals, unit length; zero where no face of positive area touches."""
    tri = verts[faces]
    n = torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1)  # 2 * area * unit normal
    acc = torch.zeros_like(verts).index_add(0, faces[:, 0], n).index_add(0, faces[:, 1], n)
    acc = acc.index_add(0, faces[:, 2], n)
    norm = acc.norm(dim=-1, keepdim=True)
    return torch.where(norm > 0, acc / torch.where(norm > 0, norm, torch.ones_like(norm)), torch.zeros_like(acc))


def closest_faces(points: Tensor, verts: Tensor, faces: Tensor, *, candidates: int = 16) -> Tensor:
    """``(P,)`` index of the exactly closest face of ``(verts, faces)`` to every point (no gradient).

    A pruned exact search, used until the accelerated ``point_mesh_distance(backend="auto")`` lands: every face
    gets a bounding sphere (centroid, radius); ``|p - c_f| - r_f`` is a lower bound of the distance from ``p`` to
    face ``f``. The ``candidates`` faces with the smallest bounds are tested exactly (Ericson's closest point); a
    point keeps that answer only when its best exact distance is below the smallest bound of every face left out
    (with a float safety margin), otherwise it is retried with 8 times more candidates (finally all faces). The
    answer is therefore the exact closest face (ties may resolve to another face at the same distance).
    """
    from torchmeshmetric.kernels.point_triangle import closest_point_on_triangle

    with torch.no_grad():
        num_f = faces.shape[0]
        k = min(candidates, num_f)
        tri = verts[faces]
        center = verts.amin(0) * 0.5 + verts.amax(0) * 0.5
        cen = tri.mean(1) - center
        rad = (tri - (cen + center)[:, None]).norm(dim=-1).amax(1)
        p = points - center
        scale = float((verts.amax(0) - verts.amin(0)).norm()) + float(p.abs().max())
        margin = 64 * torch.finfo(points.dtype).eps * max(scale, 1e-30)
        out = torch.empty(points.shape[0], dtype=torch.long, device=points.device)
        rows = max(1, (1 << 22) // max(1, num_f))
        for r0 in range(0, points.shape[0], rows):
            pc = p[r0 : r0 + rows]
            lb = torch.cdist(pc, cen) - rad
            todo = torch.arange(pc.shape[0], device=points.device)
            kk = k
            while todo.numel():
                lb_t = lb if todo.numel() == pc.shape[0] else lb[todo]
                # The (kk+1)-th smallest bound is the smallest bound among the faces left out.
                lb_k, cand = lb_t.topk(min(kk + 1, num_f), dim=1, largest=False)
                rest, cand = lb_k[:, -1], cand[:, :kk]
                t = tri[cand] - center  # (R, kk, 3, 3)
                sq = closest_point_on_triangle(pc[todo, None], t[..., 0, :], t[..., 1, :], t[..., 2, :]).sq_dists
                best_sq, j = sq.min(1)
                out[r0 + todo] = cand.gather(1, j[:, None])[:, 0]
                if kk >= num_f:
                    break
                # Exact when no left-out face can be closer.
                unsure = best_sq.clamp_min(0).sqrt() > rest - margin
                todo = todo[unsure]
                kk = min(num_f, kk * 8)
        return out
