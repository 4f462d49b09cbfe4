"""Controlled distortions of simplified sequences with a known answer, on a sequence with ground-truth motion.

The validation study (:mod:`torchmeshmetric.evaluation.validation`) and the tests inject these at known strengths
and check which distance sets respond. Everything starts from the **tracked simplification**: frame 0 simplified
once, carried to every frame by the true motion and projected onto that frame's surface, so it has (almost) no
geometric error on frame ``k`` and no flicker: the same triangles, moving with the body.

Distortions (``strength`` in the sequence's units; ``seed`` makes the random ones reproducible):

* :func:`normal_offset` — every vertex moved along the normal of the original frame's surface under it, by a
  per-frame amount: a constant amount is a steady offset (a geometric error, no flicker), ``(-1)^k s`` an
  alternating one (flicker of amplitude ``2 s``);
* :func:`surface_noise` — independent Gaussian noise along the normal (a rough surface, re-drawn every frame);
* :func:`tangential_slide` — vertices slid along the surface by a random tangent step, re-projected onto it
  (the surface barely changes: what surface distances cannot see);
* re-simplification is done with the simplifiers themselves (see the validation study).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from torch import Tensor

from torchmeshmetric.kernels import point_mesh_distance
from torchmeshmetric.registration.cache import CachedRegistration
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = [
    "Motion",
    "ground_truth_registrations",
    "normal_offset",
    "surface_normals",
    "surface_noise",
    "tangential_slide",
    "tracked_simplification",
]


#: The true motion of a sequence: ``motion(points, src, dst)`` → positions in frame ``dst`` of points of frame ``src``.
Motion = Callable[[Tensor, int, int], Tensor]


def surface_normals(points: Tensor, reference: MeshLike) -> Tensor:
    """``(P, 3)`` unit normal of the face of ``reference`` closest to each point (its surface normal there)."""
    ref = as_mesh(reference, name="reference").to(points.device, points.dtype)
    with torch.no_grad():
        face = point_mesh_distance(points, ref).face_idx
    tri = ref.verts[ref.faces[face]]
    n = torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1)
    return n / n.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(n.dtype).tiny)


def tracked_simplification(frames: Sequence[MeshLike], simplified_frame_0: MeshLike, motion: Motion) -> list[Mesh]:
    """Frame 0's simplification carried through the sequence by ``motion`` and projected onto every frame.

    Args:
        frames: the original frames.
        simplified_frame_0: the simplified frame 0.
        motion: the true motion, ``motion(points, 0, k)`` → positions in frame ``k`` (e.g.
            :meth:`~torchmeshmetric.data.DemoSequence.transfer`).

    Returns:
        One mesh per frame, all with the faces of ``simplified_frame_0``.
    """
    base = as_mesh(simplified_frame_0, name="simplified_frame_0")
    out = [base]
    for k in range(1, len(frames)):
        ref = as_mesh(frames[k]).to(base.device, base.dtype)
        moved = motion(base.verts, 0, k)
        with torch.no_grad():
            out.append(Mesh(point_mesh_distance(moved, ref).closest.detach(), base.faces, validate=False))
    return out


def ground_truth_registrations(frames: Sequence[MeshLike], motion: Motion) -> list[CachedRegistration]:
    """The registration of every original frame ``k-1`` onto frame ``k`` by the true motion (with its warp).

    The residual is measured as for any registration (registered vertices to frame ``k``'s surface): the true
    motion of the built-in sequence is exact on the limbs and approximate around the joints.
    """
    out = []
    for k in range(1, len(frames)):
        src, dst = as_mesh(frames[k - 1]), as_mesh(frames[k]).to(dtype=as_mesh(frames[k - 1]).dtype)
        verts = motion(src.verts, k - 1, k)
        with torch.no_grad():
            residual = point_mesh_distance(verts, dst).dists
        out.append(CachedRegistration(verts, residual, True, 0.0, _StepWarp(motion, k)))
    return out


class _StepWarp:
    """The true motion from frame ``k - 1`` to frame ``k`` as a warp (a picklable callable)."""

    def __init__(self, motion: Motion, k: int) -> None:
        self.motion, self.k = motion, k

    def __call__(self, points: Tensor, /) -> Tensor:
        return self.motion(points, self.k - 1, self.k)


def _along_normal(mesh: Mesh, frame: MeshLike, amount: float | Tensor) -> Mesh:
    """``mesh``, every vertex moved by ``amount`` (a number or ``(V, 1)``) along the normal of ``frame`` under it."""
    return Mesh(mesh.verts + amount * surface_normals(mesh.verts, frame), mesh.faces, validate=False)


def normal_offset(meshes: Sequence[Mesh], frames: Sequence[MeshLike], amounts: Sequence[float]) -> list[Mesh]:
    """Every vertex of ``meshes[k]`` moved by ``amounts[k]`` along the surface normal of ``frames[k]`` under it."""
    return [_along_normal(m, f, a) for m, f, a in zip(meshes, frames, amounts, strict=True)]


def surface_noise(meshes: Sequence[Mesh], frames: Sequence[MeshLike], sigma: float, *, seed: int = 0) -> list[Mesh]:
    """Independent Gaussian noise of standard deviation ``sigma`` along the normal, a new draw every frame."""
    gen = torch.Generator().manual_seed(seed)
    out = []
    for mesh, frame in zip(meshes, frames, strict=True):  # frame by frame: the draws follow the frame order
        amount = sigma * torch.randn(mesh.num_verts, 1, generator=gen, dtype=torch.float64).to(mesh.verts)
        out.append(_along_normal(mesh, frame, amount))
    return out


def tangential_slide(meshes: Sequence[Mesh], frames: Sequence[MeshLike], step: float, *, seed: int = 0) -> list[Mesh]:
    """Every vertex slid by ``step`` in a random tangent direction, then projected back onto the frame's surface."""
    gen = torch.Generator().manual_seed(seed)
    out = []
    for mesh, frame in zip(meshes, frames, strict=True):
        ref = as_mesh(frame).to(mesh.device, mesh.dtype)
        n = surface_normals(mesh.verts, ref)
        r = torch.randn(mesh.num_verts, 3, generator=gen, dtype=torch.float64).to(mesh.verts)
        tangent = r - (r * n).sum(-1, keepdim=True) * n
        tangent = tangent / tangent.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(r.dtype).tiny)
        with torch.no_grad():
            slid = point_mesh_distance(mesh.verts + step * tangent, ref).closest.detach()
        out.append(Mesh(slid, mesh.faces, validate=False))
    return out
