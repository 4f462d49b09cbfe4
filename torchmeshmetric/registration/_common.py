"""Helpers shared by the registration modules: input validation and the normalised frame."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

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


def welded_faces(verts: Tensor, faces: Tensor) -> Tensor:
    """``faces`` with every corner re-pointed to the first vertex at exactly the same position.

    Captured frames hold duplicate vertices along open seams. Split there, a vertex normal averages half of the
    vertex's faces, so the interpolated normal jumps across the seam, and which side a closest point on the seam
    takes depends on the input's last bits. Welded, both sides share one vertex and one normal; the positions, and so
    every closest point, are unchanged (a copy is at its original's position, and moves with the same skinning).
    """
    n = verts.shape[0]
    if n == 0:
        return faces
    # Rows sorted lexicographically by three stable 1-D sorts (torch.unique(dim=0) took ~80 ms on 20k rows).
    order = torch.arange(n, device=verts.device)
    for axis in (2, 1, 0):
        order = order[torch.sort(verts[order, axis], stable=True).indices]
    rows = verts[order]
    starts = torch.ones(n, dtype=torch.bool, device=verts.device)
    starts[1:] = (rows[1:] != rows[:-1]).any(dim=1)
    group = torch.empty_like(order)
    group[order] = torch.cumsum(starts, 0) - 1
    first = torch.full((int(starts.sum()),), n, device=verts.device)
    first = first.scatter_reduce(0, group, torch.arange(n, device=verts.device), "amin")
    return first[group][faces]


def normalisation(mesh: Mesh) -> tuple[Tensor, Tensor]:
    """``(center (3,), diagonal (0-dim))`` of the bounding box of the surface vertices: the registration's frame.

    The non-rigid registration works on ``(x - center) / diagonal`` so that its thresholds are fractions of the
    target's diagonal.
    """
    ref = mesh.verts[mesh.surface_vertex_mask()]
    return 0.5 * (ref.amin(0) + ref.amax(0)), (ref.amax(0) - ref.amin(0)).norm()


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """Torch on one intra-op thread inside the block, restored after (process-wide, as ``torch.set_num_threads``).

    For small dense algebra whose BLAS calls split their sums by thread (ICP's 1000 x 6 normal equations): on one
    thread they sum in one order, so the result does not depend on the caller's thread count.
    """
    previous = torch.get_num_threads()
    if previous == 1:
        yield
        return
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(previous)
