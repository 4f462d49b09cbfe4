"""Helpers shared by the registration modules: input validation and the normalised frame."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, NonFiniteError, check_same_device
from torchmeshmetric.kernels._common import range_scale
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

SAMPLINGS = ("index", "canonical", "dense")
"""The values of ``NonRigidOptions.sampling`` and ``register_rigid``'s ``sampling``."""


def check_sampling(value: object) -> str:
    """Require one of :data:`SAMPLINGS` (``register_rigid``'s ``sampling`` and ``NonRigidOptions.sampling``).

    Example:
        >>> check_sampling("canonical")
        'canonical'
    """
    if not isinstance(value, str):
        raise TypeError(f"sampling: expected one of {list(SAMPLINGS)}, found {type(value).__name__}")
    if value not in SAMPLINGS:
        raise ValueError(f"sampling: expected one of {list(SAMPLINGS)}, found {value!r}")
    return value


def coordinate_scale(*meshes: Mesh) -> float:
    """Power of two that brings the largest ``|coordinate|`` of the meshes' referenced vertices into ``[0.5, 1)``.

    1.0 where not needed. The registration computes areas, normals, squared distances and robust weights: products of
    up to four coordinates (``|ab x ac|^2``), which overflow or underflow float32 for meshes beyond ~6e4 or below ~2e-5
    units (found by review: float32 icospheres of 1e20 units failed in :func:`normalisation`, of 1e-20 units were
    called zero-area). Scaling by a power of two is exact, so the registration runs on scaled coordinates and its
    lengths are divided back; where no scaling is needed (1.0) nothing is multiplied and the result is the same bit
    for bit. The largest ``|coordinate|``, not the extent: :meth:`~torchmeshmetric.Mesh.surface_face_mask` compares
    areas with rounding relative to it. Referenced vertices only (every vertex of a mesh without faces): a stray
    unreferenced vertex at 1e6 scaled a unit float32 mesh by 2**-20, whose small faces' squared areas then lost their
    digits (found by review: the registration onto such a target failed to converge).
    """
    extent = 0.0
    for m in meshes:
        v = m.verts.detach()
        if m.num_faces:
            v = v[m.referenced_vertex_mask()]
        if v.numel():
            extent = max(extent, float(v.abs().amax()))
    scale = range_scale(extent, meshes[0].dtype, 4)
    return 1.0 if scale is None else scale


def registration_dtype(source: Mesh, target: Mesh) -> torch.dtype:
    """The dtype a registration of ``source`` onto ``target`` computes in: theirs promoted, at least float32.

    One rule for the registration (:func:`validate_pair`) and its cache key (``registration_key``), which keeps
    float32 and float64 registrations apart.
    """
    return torch.promote_types(torch.promote_types(source.dtype, target.dtype), torch.float32)


def validate_pair(source: MeshLike, target: MeshLike) -> tuple[Mesh, Mesh, float]:
    """Validate both meshes (typed errors), require one device and faces with positive total area.

    Vertices are promoted to a common floating dtype (at least float32) and multiplied by ``scale``, the exact power of
    two of :func:`coordinate_scale` (1.0, no multiplication, within the dtype's comfortable range), so that areas and
    squared distances neither overflow nor underflow; lengths computed on them are divided by ``scale`` to return to
    the input's units.

    Returns:
        ``(source, target, scale)``.
    """
    src = as_mesh(source, name="source")
    tgt = as_mesh(target, name="target")
    check_same_device({"source": src.verts, "target": tgt.verts})
    for name, m in (("source", src), ("target", tgt)):
        if m.num_verts == 0:
            raise EmptyInputError(f"{name}: expected at least one vertex, found an empty mesh")
        if m.num_faces == 0:
            raise EmptyInputError(f"{name}: expected at least one face, found none")
    dtype = registration_dtype(src, tgt)
    src, tgt = src.to(dtype=dtype), tgt.to(dtype=dtype)
    scale = coordinate_scale(src, tgt)
    if scale != 1.0:
        scaled = []
        for name, m in (("source", src), ("target", tgt)):
            verts = m.verts * scale
            if scale > 1.0 and not bool(torch.isfinite(verts).all()):
                # The scale is the surface's (coordinate_scale): an unreferenced vertex far beyond a tiny surface
                # overflows it, and the registration moved it to Inf (or refused "verts: expected finite values").
                far = float(m.verts.detach().abs().amax())
                raise NonFiniteError(
                    f"{name}: an unreferenced vertex (up to {far:.3g} from the origin) lies beyond "
                    f"{str(dtype).removeprefix('torch.')}'s range in the frame of a surface of size "
                    f"{1.0 / scale:.3g}; register in float64 (--dtype float64) or drop the unreferenced vertices"
                )
            scaled.append(Mesh(verts, m.faces, validate=False))
        src, tgt = scaled
    for name, m in (("source", src), ("target", tgt)):
        # On the scaled vertices: float32 areas of a 1e-20-unit mesh underflow to 0 (found by review).
        if not bool(m.face_areas().sum() > 0):
            raise EmptyInputError(f"{name}: expected a surface with positive area, found only zero-area faces")
        if not bool(m.surface_face_mask().any()):  # every area is rounding noise: the normals point anywhere
            largest = float(m.verts.detach()[m.referenced_vertex_mask()].abs().amax()) / scale
            raise EmptyInputError(
                f"{name}: every face is smaller than the rounding of its {str(dtype).removeprefix('torch.')} "
                f"coordinates (up to {largest:.3g} from the origin); register in float64 (--dtype float64) or "
                "move the mesh nearer the origin"
            )
    return src, tgt, scale


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
    target's diagonal. The surface mask and the norm are computed on coordinates scaled by :func:`coordinate_scale`
    (float32 areas overflow beyond ~1e19 units and underflow below ~1e-19; found by review); the scaling is exact,
    so both values are those of the input, and computed as before where no scaling is needed.
    """
    scale = coordinate_scale(mesh)
    if scale != 1.0:
        mesh = Mesh(mesh.verts * scale, mesh.faces, validate=False)
    ref = mesh.verts[mesh.surface_vertex_mask()]
    center, diagonal = 0.5 * (ref.amin(0) + ref.amax(0)), (ref.amax(0) - ref.amin(0)).norm()
    if scale != 1.0:
        center, diagonal = center / scale, diagonal / scale
    return center, diagonal


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
