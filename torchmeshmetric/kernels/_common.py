"""Small helpers shared by the kernels.

Chunk sizing, safe division and square roots, per-item centring, exact range scaling, and the checks every query
makes.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, NonFiniteError, all_finite, check_int
from torchmeshmetric.structures import batch_index

DEFAULT_MAX_MEMORY = 256 * 2**20
"""Default memory budget of one kernel intermediate, in bytes (256 MiB)."""


def dot(x: Tensor, y: Tensor) -> Tensor:
    """Row-wise dot product of 3-vectors (last dimension 3), added as ``(x0*y0 + x1*y1) + x2*y2`` on every device.

    Not ``(x * y).sum(-1)``: a reduction's order is the device's choice, and CUDA's (two threads per output of a
    size-3 dimension) is ``(x0*y0 + x2*y2) + x1*y1``, which rounds differently from the C++ (``triangle.h``
    ``dot3``) and Triton kernels, so the torch brute force chose other faces at near-ties on a GPU (review M).
    Elementwise products and adds, one op each, round the same on the CPU and on CUDA and are never fused into FMAs.
    """
    x0, x1, x2 = x.unbind(-1)
    y0, y1, y2 = y.unbind(-1)
    return (x0 * y0 + x1 * y1) + x2 * y2


def cross(x: Tensor, y: Tensor) -> Tensor:
    """Cross product over the last dimension, broadcasting leading dimensions of any rank."""
    x0, x1, x2 = x.unbind(-1)
    y0, y1, y2 = y.unbind(-1)
    return torch.stack([x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0], dim=-1)


def safe_div(num: Tensor, den: Tensor) -> Tensor:
    """``num / den`` where ``den > 0``, else 0; finite value and gradient everywhere."""
    ok = den > 0
    return torch.where(ok, num / torch.where(ok, den, torch.ones_like(den)), torch.zeros_like(num))


def safe_sqrt(sq: Tensor) -> Tensor:
    """``sqrt(sq)`` with gradient 0 (not Inf/NaN) at ``sq == 0``."""
    pos = sq > 0
    return torch.where(pos, torch.sqrt(torch.where(pos, sq, torch.ones_like(sq))), torch.zeros_like(sq))


def item_centers(x: Tensor, batch: Tensor, num_items: int) -> Tensor:
    """``(B, 3)`` centre of the bounding box of each item's rows (0 for empty items).

    Kernels subtract it before computing so that float32 accuracy is relative to the mesh size, not to
    its distance from the origin (coordinates around 1e6 keep full relative precision).
    """
    if num_items == 1 and x.shape[0] > 0:
        # One item: a plain min/max pass, no scatter (min and max are exact, so the centre is identical).
        lo1, hi1 = x.detach().aminmax(dim=0)
        return (0.5 * (lo1 + hi1))[None]
    lo = torch.full((num_items, 3), float("inf"), dtype=x.dtype, device=x.device)
    hi = torch.full((num_items, 3), float("-inf"), dtype=x.dtype, device=x.device)
    idx = batch[:, None].expand(-1, 3)
    lo = lo.scatter_reduce(0, idx, x.detach(), reduce="amin")
    hi = hi.scatter_reduce(0, idx, x.detach(), reduce="amax")
    center = 0.5 * (lo + hi)
    return torch.where(torch.isfinite(center), center, torch.zeros_like(center))


def item_rows(lengths: Tensor, num_rows: int, centers: Tensor) -> tuple[Tensor, Tensor]:
    """``(batch (N,), centre of each row)`` of ``N`` packed rows of items whose ``(B, 3)`` centres are known.

    One item: the batch is zeros and the centre ``(1, 3)`` broadcasts (no batch expansion, no gather: same values).
    """
    if centers.shape[0] == 1:
        return torch.zeros(num_rows, dtype=torch.long, device=centers.device), centers
    batch = batch_index(lengths, num_rows)
    return batch, centers[batch]


def referenced_rows(faces: Tensor, num_verts: int) -> Tensor | None:
    """``(U,)`` ascending rows of the vertices some face references, or ``None`` when every vertex is referenced.

    The centre and the range scale of a mesh are taken from these rows only: a vertex no face uses is no part of the
    surface, and one far away (captured frames carry stray unreferenced vertices) moved the centre off the surface,
    so float32 lost the digits of every short distance (found by review: one unreferenced vertex at 1e9 made a point
    0.29 from a unit sphere measure 3e-8). ``None`` keeps the usual case (every vertex referenced) on the pass over
    all rows, bit for bit what it computed before. One ``bincount`` (~0.14 ms for 40k faces on one CPU core, half
    the cost of a boolean scatter), read back once per index: the faces of an index never change.

    Args:
        faces: ``(F, 3)`` int64 vertex rows (global rows of a packed batch), validated to lie in ``[0, num_verts)``.
        num_verts: ``V``, the number of packed vertices.

    Returns:
        The referenced rows, or ``None``.
    """
    counts = torch.bincount(faces.reshape(-1), minlength=num_verts)
    used = counts > 0
    return None if bool(used.all()) else used.nonzero().squeeze(1)


def centred(x: Tensor, lengths: Tensor, rows: Tensor | None = None) -> tuple[Tensor, Tensor, Tensor]:
    """Per-item bounding-box centring of packed rows: ``(centres (B, 3), row centres (1 or N, 3), batch (N,))``.

    Args:
        x: ``(N, 3)`` packed rows.
        lengths: ``(B,)`` rows per item.
        rows: the rows whose bounding box gives each item's centre (:func:`referenced_rows`); ``None``: every row.
            An item with none of them is centred on 0.

    Returns:
        The item centres, the centre of each row (``(1, 3)`` for one item: it broadcasts), the item of each row.
    """
    num_items = int(lengths.numel())
    batch = (
        torch.zeros(x.shape[0], dtype=torch.long, device=x.device)
        if num_items == 1
        else batch_index(lengths, int(x.shape[0]))
    )
    if rows is None:
        centers = item_centers(x, batch, num_items)
    else:
        centers = item_centers(x.index_select(0, rows), batch.index_select(0, rows), num_items)
    return centers, (centers if num_items == 1 else centers[batch]), batch


def check_queries(
    points: Tensor,
    points_lengths: Tensor,
    prim_lengths: Tensor,
    *,
    count_error: str,
    lacking_error: str,
    prims_everywhere: bool = False,
) -> None:
    """Raise unless the query points fit the items they are measured against.

    Args:
        points: ``(P, 3)`` packed query points.
        points_lengths: ``(B',)`` points per item.
        prim_lengths: ``(B,)`` primitives (faces, reference points) per item.
        count_error: ``ValueError`` message when ``B' != B``, formatted with ``items`` (``B``) and ``sets`` (``B'``).
        lacking_error: ``EmptyInputError`` message for an item with points but no primitive, formatted with
            ``item`` and ``points``.
        prims_everywhere: the caller knows every item has primitives (a kept index, checked once): the check
            that reads ``prim_lengths`` back from the device is skipped.

    Raises:
        ValueError: when there is not one point set per item.
        EmptyInputError: when there is no point at all, or an item has points but no primitive.
    """
    num_items, num_sets = int(prim_lengths.numel()), int(points_lengths.numel())
    if num_sets != num_items:
        raise ValueError(count_error.format(items=num_items, sets=num_sets))
    if points.shape[0] == 0:
        raise EmptyInputError("points: expected at least one point, found an empty point set")
    if prims_everywhere or (
        num_items and int(prim_lengths.min()) > 0
    ):  # the usual case, one reduction: every item has primitives
        return
    lacking = (points_lengths > 0) & (prim_lengths == 0)
    if bool(lacking.any()):
        b = int(lacking.nonzero()[0, 0])
        raise EmptyInputError(lacking_error.format(item=b, points=int(points_lengths[b])))


def check_max_memory(max_memory: object) -> int:
    """Require a positive int number of bytes for ``max_memory`` (every backend and entry point checks it alike)."""
    return check_int(max_memory, "max_memory", low=1)


def pair_chunks(num_rows: int, num_cols: int, bytes_per_pair: int, max_memory: int) -> tuple[int, int]:
    """Row and column chunk sizes so that ``rows * cols * bytes_per_pair <= max_memory`` (at least 1 x 1)."""
    check_max_memory(max_memory)
    pairs = max(1, max_memory // max(1, bytes_per_pair))
    cols = max(1, min(num_cols, pairs // max(1, min(num_rows, 256))))
    rows = max(1, min(num_rows, pairs // cols))
    return rows, cols


def range_scale(extent: float, dtype: torch.dtype, degree: int) -> float | None:
    """Power of two that brings ``extent`` into ``[0.5, 1)``, or ``None`` when no scaling is needed.

    A kernel whose intermediates are products of ``degree`` coordinates (squared distances: 2; the squared normal
    ``|ab x ac|^2`` of a triangle: 4) overflows or underflows ``dtype`` for coordinates of extreme magnitude: float32
    breaks down for meshes beyond ~1e9 or below ~1e-9 units. Scaling by a power of two is exact (only the exponent
    changes), so the kernel computes on scaled coordinates and divides its distances back, bit for bit the same
    result where no scaling was needed. ``None`` while ``extent`` is within ``2**(+-maxexp / (2 * degree))``.

    A subnormal ``extent`` (float32 below ~1.2e-38, float64 below ~2.2e-308) would need a scale beyond the dtype's
    largest finite power of two (float32 1e-40 asked for ``2**132``, an ``inf`` in float32, and float64 1e-310 for
    ``2**1030``, an ``OverflowError`` in Python): the scale is capped at ``2**(maxexp - 1)``, which still brings the
    smallest subnormal to ``2**-22`` (float32; ``2**-51`` in float64), where products of 4 coordinates stay normal.
    """
    if not (extent > 0 and math.isfinite(extent)):
        return None
    exponent = math.frexp(extent)[1]
    maxexp = math.frexp(torch.finfo(dtype).max)[1]
    limit = maxexp // (2 * degree)
    return None if -limit <= exponent <= limit else math.ldexp(1.0, min(-exponent, maxexp - 1))


def in_own_frame(magnitude: Tensor, extent: float, degree: int) -> Tensor | None:
    """``(P,)`` bool: the points the primitives' own frame can measure, or ``None`` when it can measure them all.

    A one-off query scaled for its points too (:func:`range_scale` of the larger of the primitives' ``extent`` and
    the points' largest centred ``|coordinate|``), so that a point far from a small mesh is measured, not refused.
    One far point then shrank every coordinate: float32, unit sphere, a query point at 1e10 moved the other points'
    distances by 0.03 (the faces' squared areas fell into subnormals), one at 1e30 made them all 0. The points
    marked here are those whose scaled magnitude stays within the range :func:`range_scale` keeps (below
    ``2**(maxexp / (2 * degree))``) in the primitives' frame: they are measured in it, the frame a kept index uses;
    the others in a frame scaled for them too. A power of two scales exactly, so a point measured in either frame
    gets the same bits unless one of them under- or overflows.

    Args:
        magnitude: ``(P,)`` each point's largest centred ``|coordinate|`` (finite, unscaled).
        extent: the primitives' largest centred ``|coordinate|``.
        degree: as :func:`range_scale`.

    Returns:
        The mask, or ``None`` when it would be all ``True`` (one frame serves every point).
    """
    dtype = magnitude.dtype
    scale = range_scale(extent, dtype, degree)
    bound = math.ldexp(1.0, math.frexp(torch.finfo(dtype).max)[1] // (2 * degree)) / (1.0 if scale is None else scale)
    if magnitude.numel() == 0 or float(magnitude.amax()) < bound:
        return None
    return magnitude < bound


def rows_of(mask: Tensor, batch: Tensor, num_items: int) -> tuple[Tensor, Tensor]:
    """``(rows (Q,), lengths (B,))`` of the packed rows ``mask`` selects (item order is kept)."""
    rows = mask.nonzero().squeeze(1)
    return rows, torch.bincount(batch.index_select(0, rows), minlength=num_items)


def merge_rows(num_rows: int, rows: tuple[Tensor, Tensor], values: tuple[Tensor, Tensor]) -> Tensor:
    """``(num_rows, ...)`` with ``values[k]`` at ``rows[k]`` (the two row sets partition the rows; differentiable)."""
    out = values[0].new_empty((num_rows, *values[0].shape[1:]))
    return out.index_put((rows[0],), values[0]).index_put((rows[1],), values[1])


ROUNDING_ULPS = 64.0
"""Rounding allowance of the exact kernels, in ulps of an item's largest centred |coordinate| (and of a distance)."""


def rounding_slack(scale: Tensor) -> Tensor:
    """Absolute rounding level of values computed on centred coordinates of largest magnitude ``scale``.

    :data:`ROUNDING_ULPS` ulps of ``scale`` (``scale``'s dtype): the certified pruning slack of the ``"pruned"``
    backend and of the C++ BVH (``slack_of_scale`` in ``bvh.cpp``). (The surface losses' on-surface floor is the
    point's own, :data:`torchmeshmetric.kernels.danskin.GRADIENT_ULPS`, not this item-wide bound.)
    """
    return ROUNDING_ULPS * torch.finfo(scale.dtype).eps * scale


def check_representable(dists: Tensor, name: str) -> None:
    """Raise when finite inputs gave non-finite distances: the dtype cannot hold them (e.g. float32 beyond ~1e19).

    Inputs are checked where they enter; a ``Mesh(..., validate=False)`` is not, so a NaN there ends here too, and
    the message names that cause as well (it spoke of overflow alone).
    """
    if dists.numel() and not all_finite(dists):
        raise NonFiniteError(
            f"{name}: the distances overflow {dists.dtype} (coordinates too large for its range, "
            f"max {torch.finfo(dists.dtype).max:.3g}); compute in float64 (or, for NaN coordinates, check the mesh: "
            "one built with validate=False is not checked)"
        )
