"""Exact point-to-triangle primitives (Ericson 2004, *Real-Time Collision Detection*, §5.1.5): a leaf module.

The closest point of a triangle ``(a, b, c)`` to ``p`` lies in one of seven Voronoi regions: the three vertex
regions, the three edge regions and the face region. Ericson selects the region from the signs of six dot
products (``d1 .. d6``) and evaluates one formula. Vectorised over millions of pairs, we evaluate the
closed form of every region at once — the clamped projection onto each edge segment covers its two
vertex regions and its edge region; the barycentric projection onto the plane covers the face region when
it falls inside — and keep the nearest candidate. In exact arithmetic that is Ericson's answer; in floating
point it never divides by a vanishing area, so zero-area and collinear triangles (whose closest point is on
one of their edges) need no absolute epsilon.

Every candidate is computed as a difference vector ``p - q`` (never as ``|p|^2 - 2 p.q + |q|^2``), and every
item is centred on its bounding box first, so float32 results stay accurate for meshes far from the origin.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import ShapeError, check_finite, check_float, check_tensor
from torchmeshmetric.kernels._common import check_representable, cross, dot, safe_div

__all__ = ["ClosestPointOnTriangle", "closest_point_on_triangle", "region_candidates", "triangle_range_scale"]


class ClosestPointOnTriangle(NamedTuple):
    """Result of :func:`closest_point_on_triangle`.

    Attributes:
        closest: ``(..., 3)`` closest point on the triangle.
        bary: ``(..., 3)`` its barycentric coordinates ``(u, v, w)``, ``closest = u a + v b + w c``.
        sq_dists: ``(...)`` **squared** Euclidean distance from the query point.

    Example:
        >>> import torch
        >>> a, b, c = torch.tensor([0.0, 0, 0]), torch.tensor([1.0, 0, 0]), torch.tensor([0.0, 1, 0])
        >>> r = closest_point_on_triangle(torch.tensor([[0.25, 0.25, 1.0]]), a, b, c)
        >>> r.closest.tolist(), r.bary.tolist(), r.sq_dists.tolist()
        ([[0.25, 0.25, 0.0]], [[0.5, 0.25, 0.25]], [1.0])
    """

    closest: Tensor
    bary: Tensor
    sq_dists: Tensor


def region_candidates(ap: Tensor, bp: Tensor, ab: Tensor, ac: Tensor, bc: Tensor) -> tuple[Tensor, ...]:
    """Parameters and squared distances of the four region candidates, broadcast over leading dims.

    The one expression of the squared point-triangle distance: every selection backend (and ``triangle.h`` in C++)
    computes these operations in this order, so all of them choose the same face.

    Args:
        ap: ``(..., 3)`` ``p - a``.
        bp: ``(..., 3)`` ``p - b``.
        ab: ``(..., 3)`` ``b - a``.
        ac: ``(..., 3)`` ``c - a``.
        bc: ``(..., 3)`` ``c - b``.

    Returns:
        ``(t_ab, t_ac, t_bc, v, w, sq)`` with ``sq`` of shape ``(..., 4)`` ordered ``[edge AB, edge AC, edge BC,
        face]``; the face entry is ``inf`` where the plane projection lies outside the triangle or the triangle has
        zero area.

    Example:
        >>> import torch
        >>> a, b, c = torch.zeros(3), torch.tensor([1.0, 0, 0]), torch.tensor([0.0, 1, 0])
        >>> p = torch.tensor([0.25, 0.25, 1.0])
        >>> region_candidates(p - a, p - b, b - a, c - a, c - b)[-1].tolist()  # edges AB, AC, BC, then the face
        [1.0625, 1.0625, 1.125, 1.0]
    """
    # Edge segments, clamped: vertex regions (t = 0 or 1) and edge regions (0 < t < 1).
    t_ab = safe_div(dot(ap, ab), dot(ab, ab)).clamp(0.0, 1.0)
    t_ac = safe_div(dot(ap, ac), dot(ac, ac)).clamp(0.0, 1.0)
    t_bc = safe_div(dot(bp, bc), dot(bc, bc)).clamp(0.0, 1.0)
    d_ab = ap - t_ab[..., None] * ab
    d_ac = ap - t_ac[..., None] * ac
    d_bc = bp - t_bc[..., None] * bc
    # Face region: barycentrics from the normal n = ab x ac (no d00*d11 - d01^2 cancellation).
    n = cross(ab, ac)
    nn = dot(n, n)
    v = safe_div(dot(cross(ap, ac), n), nn)
    w = safe_div(dot(cross(ab, ap), n), nn)
    # u = 1 - v - w as the face's barycentric is computed, not v + w <= 1: the two round differently, and a point
    # above an edge was taken as inside with u = -1.1e-16 (found by hypothesis, 2026-12-07: 7 % of the points above
    # edge BC of random triangles), a closest point off the triangle by rounding.
    inside = (nn > 0) & (v >= 0) & (w >= 0) & (1 - v - w >= 0)
    d_f = ap - v[..., None] * ab - w[..., None] * ac
    sq_f = torch.where(inside, dot(d_f, d_f), torch.full_like(nn, float("inf")))
    sq = torch.stack([dot(d_ab, d_ab), dot(d_ac, d_ac), dot(d_bc, d_bc), sq_f], dim=-1)
    return t_ab, t_ac, t_bc, v, w, sq


def closest_point_on_triangle(points: Tensor, a: Tensor, b: Tensor, c: Tensor) -> ClosestPointOnTriangle:
    """Closest point on triangles ``(a, b, c)`` to ``points``, elementwise with broadcasting.

    Exact in all seven Voronoi regions (Ericson 2004, §5.1.5) and for degenerate (zero-area, collinear,
    repeated-vertex) triangles, at any magnitude: where the region test's products of four coordinates would
    overflow or underflow the dtype (float32 edges beyond ~1e9 or below ~1e-9; float64 beyond ~1e76), that
    triangle and its point are scaled by an exact power of two (:func:`triangle_range_scale`), bit for bit the
    answer of the unscaled computation wherever that neither overflows nor underflows. Differentiable w.r.t. all
    inputs; gradients are finite everywhere.

    Args:
        points: ``(..., 3)`` query points.
        a: ``(..., 3)`` first corners.
        b: ``(..., 3)`` second corners.
        c: ``(..., 3)`` third corners.

    Returns:
        :class:`ClosestPointOnTriangle` ``(closest, bary, sq_dists)``; ``sq_dists`` is squared.

    Raises:
        TypeError, DTypeError, ShapeError, NonFiniteError: an argument that is not a float tensor of shape
            ``(..., 3)`` with finite values, or shapes that do not broadcast; the error names the argument.
        NonFiniteError: a squared distance the dtype cannot hold (float32 beyond ~3.4e38, a distance of ~1.8e19).

    Example:
        >>> import torch
        >>> a, b, c = torch.tensor([0., 0, 0]), torch.tensor([1., 0, 0]), torch.tensor([0., 1, 0])
        >>> r = closest_point_on_triangle(torch.tensor([0.25, 0.25, 2.0]), a, b, c)
        >>> r.closest.tolist(), r.sq_dists.item()
        ([0.25, 0.25, 0.0], 4.0)
    """
    args = (("points", points), ("a", a), ("b", b), ("c", c))
    for name, x in args:
        check_tensor(x, name, "a tensor of shape (..., 3)")
        check_float(x, name)
        if x.dim() == 0 or x.shape[-1] != 3:
            raise ShapeError(f"{name}: expected shape (..., 3), found ({', '.join(map(str, x.shape))})")
        check_finite(x, name)
    try:
        torch.broadcast_shapes(*(x.shape for _, x in args))
    except RuntimeError:
        found = ", ".join(f"{n} {tuple(x.shape)}" for n, x in args)
        raise ShapeError(f"points, a, b, c: expected shapes that broadcast, found {found}") from None
    scale = triangle_range_scale(points, a, b, c)
    if scale is None:
        result = closest_point_on_triangle_unchecked(points, a, b, c)
    else:
        # The region is chosen on scaled copies (barycentrics do not depend on the scale); the closest point and its
        # squared distance are formed from them in the caller's units, as the unscaled path forms them.
        bary = closest_point_on_triangle_unchecked(points * scale, a * scale, b * scale, c * scale).bary
        closest = bary[..., 0:1] * a + bary[..., 1:2] * b + bary[..., 2:3] * c
        diff = points - closest
        result = ClosestPointOnTriangle(closest, bary, dot(diff, diff))
    check_representable(result.sq_dists, "points")
    return result


def triangle_range_scale(points: Tensor, a: Tensor, b: Tensor, c: Tensor) -> Tensor | None:
    """``(..., 1)`` per-pair power-of-two scale for :func:`region_candidates`, or ``None`` where no pair needs one.

    The region test forms products of four coordinate differences (``|ab x ac|^2``, ``(ap x ac) . n``): with the
    largest difference ``m = max |ab|, |ac|, |ap|`` at or above ``2**(maxexp / 4 - 2)`` they overflow (float32:
    edges of 1e10 gave a NaN barycentric, the face candidate was dropped and an edge point returned, a squared
    distance 5x too large; review V), and with the largest edge ``e`` below ``2**-(maxexp / 4 - 2)`` the squared
    normal underflows. Such a pair is scaled so that ``m`` comes into ``[0.5, 1)``, or, where that would take ``e``
    below the bound (a point far from a small triangle), just enough to keep ``e`` above it; every other pair gets
    1, so scaled and unscaled pairs give the same bits where nothing over- or underflows. The scale is capped at
    ``2**(maxexp - 2)`` (subnormal pairs). A point far from a small triangle has its distance right to rounding,
    but once its candidates' squared distances tie in the dtype (float32: beyond ~2**12 times the triangle's size,
    scaled or not) the first of them gives its closest point (the library's tie rule); beyond
    ``2**(maxexp / 2 + maxexp / 4 - 2)`` (float32 2**94, float64 2**766) the squares overflow in the scaled frame
    and the same holds.

    Args:
        points: ``(..., 3)`` query points (finite).
        a: ``(..., 3)`` first corners.
        b: ``(..., 3)`` second corners.
        c: ``(..., 3)`` third corners.

    Returns:
        The scale, broadcast over the inputs' leading shape with a trailing 1, or ``None``.

    Example:
        >>> import torch
        >>> a, b, c = torch.zeros(3), torch.tensor([1e10, 0, 0]), torch.tensor([0, 1e10, 0])
        >>> triangle_range_scale(torch.tensor([0.2e10, 0.3e10, 0.1e10]), a, b, c).item() == 2.0**-34
        True
        >>> triangle_range_scale(torch.ones(3), a / 1e10, b / 1e10, c / 1e10) is None
        True
    """
    with torch.no_grad():
        # Halved, so that the differences of finite coordinates cannot overflow (the exponent is all that is used).
        pa, pb, pc, pp = (x.detach() * 0.5 for x in (a, b, c, points))
        edge = torch.maximum((pb - pa).abs().amax(-1), (pc - pa).abs().amax(-1))
        largest = torch.maximum(edge, (pp - pa).abs().amax(-1))
        maxexp = math.frexp(torch.finfo(largest.dtype).max)[1]
        bound = maxexp // 4 - 2  # float32 30, float64 254
        _, m_exp = torch.frexp(largest)
        _, e_exp = torch.frexp(edge)
        m_exp, e_exp = m_exp + 1, e_exp + 1  # the halving
        needs = (m_exp > bound) | ((edge > 0) & (e_exp < -bound))
        if not bool(needs.any()):
            return None
        exponent = torch.where(edge > 0, torch.maximum(-m_exp, 1 - bound - e_exp), -m_exp)
        # A subnormal pair would ask for more than the largest finite power of two; 2**(maxexp - 2) is enough.
        exponent = exponent.clamp_max(maxexp - 2)
        exponent = torch.where(needs & (largest > 0), exponent, torch.zeros_like(exponent))
        return torch.ldexp(torch.ones_like(largest), exponent)[..., None]


def closest_point_on_triangle_unchecked(points: Tensor, a: Tensor, b: Tensor, c: Tensor) -> ClosestPointOnTriangle:
    """:func:`closest_point_on_triangle` for inputs the caller has validated (float, finite, ``(..., 3)``)."""
    ab, ac, bc = b - a, c - a, c - b
    ap, bp = points - a, points - b
    t_ab, t_ac, t_bc, v, w, sq = region_candidates(ap, bp, ab, ac, bc)
    region = sq.detach().argmin(-1, keepdim=True)
    zero = torch.zeros_like(t_ab)
    # Barycentrics of each candidate, (..., 4, 3).
    bary_all = torch.stack(
        [
            torch.stack([1 - t_ab, t_ab, zero], -1),
            torch.stack([1 - t_ac, zero, t_ac], -1),
            torch.stack([zero, 1 - t_bc, t_bc], -1),
            torch.stack([1 - v - w, v, w], -1),
        ],
        dim=-2,
    )
    shape = torch.broadcast_shapes(bary_all.shape[:-2], region.shape[:-1])
    bary_all = bary_all.expand(*shape, 4, 3)
    bary = bary_all.gather(-2, region.expand(*shape, 1)[..., None].expand(*shape, 1, 3)).squeeze(-2)
    closest = bary[..., 0:1] * a + bary[..., 1:2] * b + bary[..., 2:3] * c
    diff = points - closest
    return ClosestPointOnTriangle(closest, bary, dot(diff, diff))
