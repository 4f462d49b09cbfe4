"""Differentiable MPEG geometry terms (D1, D2, their PSNR) and a grid sampling with gradients to the vertices.

The same torch code runs on CPU and CUDA, in float32 or float64, on the library's exact nearest-neighbour kernel
(:func:`torchmeshmetric.kernels.nearest_vertex_distance`). Values equal :func:`mpeg_compare`'s where every point has a
single nearest neighbour; where several are exactly equidistant, :func:`mpeg_compare` averages their D2 terms as
mmetric does, and these losses take the lowest-index one (a choice with no effect on D1 and a gradient defined
almost everywhere).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import torch
from torch import Tensor, nn

from torchmeshmetric._checks import (
    check_finite,
    check_flag,
    check_float,
    check_non_empty,
    check_same_device,
    check_shape,
    common_dtype,
)
from torchmeshmetric.kernels import nearest_vertex_distance
from torchmeshmetric.mpeg.sampling.grid_sampling import grid_hits, unique_vertex_rows
from torchmeshmetric.stats.statistics import psnr_from_mse
from torchmeshmetric.structures import Mesh

__all__ = [
    "MpegGeometryLoss",
    "differentiable_grid_sample",
    "mpeg_geometry_loss",
    "point_to_plane_mse",
    "point_to_point_mse",
    "mpeg_psnr_from_mse",
]

Term = Literal["d1", "d2"]


def _check_points(x: Tensor, name: str) -> None:
    check_shape(x, ("N", 3), name)
    check_float(x, name)
    check_non_empty(x, name)
    check_finite(x, name)


def point_to_point_mse(points: Tensor, ref_points: Tensor) -> Tensor:
    """D1 of one direction: mean over ``points`` of the squared distance to the nearest reference point.

    Args:
        points: ``(P, 3)`` points (the loop cloud; gradients flow to it and to ``ref_points``).
        ref_points: ``(R, 3)`` points searched.

    Returns:
        Scalar tensor.

    Example:
        >>> import torch
        >>> point_to_point_mse(torch.tensor([[0.0, 0, 1]]), torch.zeros(1, 3)).item()
        1.0
    """
    _check_points(points, "points")
    _check_points(ref_points, "ref_points")
    r = nearest_vertex_distance(points, ref_points)
    return (r.dists * r.dists).mean()


def point_to_plane_mse(points: Tensor, ref_points: Tensor, ref_normals: Tensor) -> Tensor:
    """D2 of one direction: mean of the squared error to the nearest reference point, projected on its normal.

    Args:
        points: ``(P, 3)`` points.
        ref_points: ``(R, 3)`` points searched.
        ref_normals: ``(R, 3)`` their normals (mmetric's are unit face normals, averaged where points merge);
            finite, float32 or float64.

    Returns:
        Scalar tensor. A point exactly equidistant from several reference points projects on the normal of the one
        the nearest-point kernel returns (which depends on the reference points' order: reordering them can change
        the loss); only :func:`~torchmeshmetric.mpeg.mpeg_compare` averages equidistant neighbours, as mmetric.

    Raises:
        ShapeError: ``ref_normals`` is not ``(R, 3)``.
        DTypeError: ``ref_normals`` is not float32 or float64.
        NonFiniteError: ``ref_normals`` holds NaN or Inf.

    Example:
        >>> import torch
        >>> n = torch.tensor([[0.0, 0, 1]])
        >>> point_to_plane_mse(torch.tensor([[3.0, 0, 2]]), torch.zeros(1, 3), n).item()
        4.0
    """
    _check_points(points, "points")
    _check_points(ref_points, "ref_points")
    check_shape(ref_normals, (ref_points.shape[0], 3), "ref_normals")
    check_float(ref_normals, "ref_normals")
    check_same_device({"points": points, "ref_points": ref_points, "ref_normals": ref_normals})
    check_finite(ref_normals, "ref_normals")  # a NaN normal gave a NaN loss in silence (found by review)
    idx = nearest_vertex_distance(points, ref_points).idx
    err = points - ref_points[idx]
    proj = (err * ref_normals[idx].to(err.dtype)).sum(dim=-1)
    return (proj * proj).mean()


def mpeg_psnr_from_mse(mse: Tensor, peak: float, factor: float = 3.0) -> Tensor:
    """MPEG's ``10 log10(factor peak^2 / mse)`` as a differentiable tensor (``inf`` at zero error, as mmetric).

    The library's :func:`torchmeshmetric.stats.psnr_from_mse` (the paper's ``10 log10(peak^2 / mse)``) applied to
    ``mse / factor``: the two conventions differ by ``10 log10(3)`` = 4.77 dB for geometry.

    Args:
        mse: mean squared errors (any shape, ``>= 0``), differentiable.
        peak: the PSNR peak, a finite number ``> 0``.
        factor: mmetric's factor of ``peak^2`` (3 for geometry: the squared diagonal of a unit cube).

    Returns:
        float64 PSNRs in dB, of ``mse``'s shape.

    Raises:
        ValueError: ``peak`` is not a positive finite number, or an ``mse`` is negative or NaN.

    Example:
        >>> import torch
        >>> round(mpeg_psnr_from_mse(torch.tensor(1e-4), 1.0).item(), 4)
        44.7712
    """
    if not (math.isfinite(peak) and peak > 0):
        raise ValueError(f"peak: expected a positive finite number, found {peak!r}")
    return psnr_from_mse(mse / factor, peak)


def mpeg_geometry_loss(
    dis_points: Tensor,
    ref_points: Tensor,
    *,
    term: Term = "d1",
    ref_normals: Tensor | None = None,
    dis_normals: Tensor | None = None,
    reduction: Literal["max", "mean"] = "max",
) -> Tensor:
    """Symmetric MPEG D1 or D2 MSE of a distorted cloud against a reference, differentiable.

    ``reduction="max"`` is MPEG's symmetric figure (the larger of the two directions, the ``mseF`` of mmetric);
    ``"mean"`` averages both directions (smoother as a loss: both directions always receive gradients).

    Args:
        dis_points: ``(P, 3)`` distorted points (e.g. :func:`differentiable_grid_sample` of the decoded mesh).
        ref_points: ``(R, 3)`` reference points.
        term: ``"d1"`` (point-to-point) or ``"d2"`` (point-to-plane).
        ref_normals: ``(R, 3)`` reference normals (D2).
        dis_normals: ``(P, 3)`` distorted normals (D2's reference -> distorted direction; mmetric uses the distorted
            cloud's own normals).
        reduction: ``"max"`` (MPEG) or ``"mean"``.

    Returns:
        Scalar tensor, in the promoted dtype of the two clouds (each cloud's gradient in its own dtype).

    Raises:
        ValueError: D2 without the normals it needs, or an unknown term / reduction.

    Example:
        >>> import torch
        >>> ref = torch.tensor([[0.0, 0, 0], [1, 0, 0]])
        >>> dis = torch.tensor([[0.0, 0.1, 0], [1, 0, 0]], requires_grad=True)
        >>> loss = mpeg_geometry_loss(dis, ref)
        >>> loss.backward()
        >>> round(loss.item(), 6), dis.grad[0].tolist()
        (0.005, [0.0, 0.10000000149011612, 0.0])
    """
    # The dtype rule (docs/concepts.md, Precision): both clouds in their promoted dtype, each cast once, so that a
    # point used by both directions gets its gradient summed in that dtype and rounded once to its own.
    _check_points(dis_points, "dis_points")
    _check_points(ref_points, "ref_points")
    dtype = common_dtype(dis_points.dtype, ref_points.dtype)
    dis_points, ref_points = dis_points.to(dtype), ref_points.to(dtype)
    if term == "d1":
        a = point_to_point_mse(ref_points, dis_points)
        b = point_to_point_mse(dis_points, ref_points)
    elif term == "d2":
        if ref_normals is None or dis_normals is None:
            raise ValueError("ref_normals, dis_normals: D2 needs the normals of both clouds")
        for name, normals, pts in (("ref_normals", ref_normals, ref_points), ("dis_normals", dis_normals, dis_points)):
            check_shape(normals, (pts.shape[0], 3), name)  # named here: point_to_plane_mse calls both ref_normals
            check_float(normals, name)
            check_finite(normals, name)
        a = point_to_plane_mse(ref_points, dis_points, dis_normals)
        b = point_to_plane_mse(dis_points, ref_points, ref_normals)
    else:
        raise ValueError(f"term: expected 'd1' or 'd2', found {term!r}")
    if reduction == "max":
        return torch.maximum(a, b)
    if reduction == "mean":
        return 0.5 * (a + b)
    raise ValueError(f"reduction: expected 'max' or 'mean', found {reduction!r}")


class MpegGeometryLoss(nn.Module):
    """:func:`mpeg_geometry_loss` as a module (``forward(dis_points, ref_points, ...)``).

    Example:
        >>> import torch
        >>> MpegGeometryLoss("d1")(torch.zeros(1, 3), torch.ones(1, 3)).item()
        3.0
    """

    def __init__(self, term: Term = "d1", reduction: Literal["max", "mean"] = "max") -> None:
        super().__init__()
        if term not in ("d1", "d2"):
            raise ValueError(f"term: expected 'd1' or 'd2', found {term!r}")
        if reduction not in ("max", "mean"):
            raise ValueError(f"reduction: expected 'max' or 'mean', found {reduction!r}")
        self.term: Term = term
        self.reduction: Literal["max", "mean"] = reduction

    def forward(
        self,
        dis_points: Tensor,
        ref_points: Tensor,
        ref_normals: Tensor | None = None,
        dis_normals: Tensor | None = None,
    ) -> Tensor:
        """The loss of ``dis_points`` against ``ref_points``."""
        return mpeg_geometry_loss(
            dis_points,
            ref_points,
            term=self.term,
            ref_normals=ref_normals,
            dis_normals=dis_normals,
            reduction=self.reduction,
        )


def differentiable_grid_sample(
    verts: Tensor,
    faces: Tensor,
    grid_size: int = 1024,
    *,
    use_normal: bool = True,
    box: tuple[object, object] | None = None,
) -> tuple[Tensor, Tensor]:
    """The grid samples of mmetric, as functions of the mesh vertices (for training against MPEG figures).

    Which rays hit which faces is decided by :func:`grid_hits` (mmetric's float32 arithmetic, no gradient); each
    hit point is then recomputed in torch as the ray's intersection with its face's plane, so it moves along its ray
    when the vertices move, and the normals follow the faces. The values equal :func:`grid_sample`'s up to the
    dtype's rounding.

    Args:
        verts: ``(V, 3)`` float vertices (any device; gradients flow to them).
        faces: ``(F, 3)`` integer faces.
        grid_size: grid steps over the box's longest side.
        use_normal: mmetric's ``--useNormal``.
        box: ``(min, max)`` sampling box (default the mesh's box, from the current vertices).

    Returns:
        ``(points (N, 3), normals (N, 3))`` on ``verts``' device and dtype.

    Example:
        >>> import torch
        >>> v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0.5]], requires_grad=True)
        >>> p, n = differentiable_grid_sample(v, torch.tensor([[0, 1, 2]]), 3, box=([0, 0, 0], [1, 1, 1]))
        >>> p[:, 2].sum().backward()  # lifting the whole mesh by h lifts each of the 6 points by h
        >>> p.shape, v.grad[:, 2].sum().item()
        (torch.Size([6, 3]), 6.0)
    """
    use_normal = check_flag(use_normal, "use_normal")
    check_shape(verts, ("V", 3), "verts")
    check_float(verts, "verts")
    check_finite(verts, "verts")
    hits = grid_hits(Mesh(verts.detach().cpu(), faces.detach().cpu()), grid_size, use_normal=use_normal, box=box)  # type: ignore[arg-type]
    kept = unique_vertex_rows(hits.points, hits.normals, None)
    dev, dt = verts.device, verts.dtype
    f = torch.as_tensor(hits.faces[hits.face_idx[kept]], device=dev)
    axis = torch.as_tensor(hits.axis[kept], device=dev)
    origin = torch.as_tensor(np.ascontiguousarray(hits.origin[kept]), device=dev).to(dt)
    v0, v1, v2 = verts[f[:, 0]], verts[f[:, 1]], verts[f[:, 2]]
    normal = torch.linalg.cross(v1 - v0, v2 - v0)
    normal = normal / normal.norm(dim=-1, keepdim=True)
    # plane through v0 with normal n: the ray origin + t e_axis meets it at t = n.(v0 - origin) / n_axis
    n_axis = normal.gather(1, axis[:, None])[:, 0]
    t = (normal * (v0 - origin)).sum(dim=-1) / n_axis
    points = origin + torch.nn.functional.one_hot(axis, 3).to(dt) * t[:, None]
    return points, normal
