"""Small helpers shared by the kernels (chunk sizing, safe division and square roots, per-item centring)."""

from __future__ import annotations

import math

import torch
from torch import Tensor

from torchmeshmetric._checks import NonFiniteError

DEFAULT_MAX_MEMORY = 256 * 2**20
"""Default memory budget of one kernel intermediate, in bytes (256 MiB)."""


def dot(x: Tensor, y: Tensor) -> Tensor:
    """Row-wise dot product over the last dimension."""
    return (x * y).sum(-1)


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


def pair_chunks(num_rows: int, num_cols: int, bytes_per_pair: int, max_memory: int) -> tuple[int, int]:
    """Row and column chunk sizes so that ``rows * cols * bytes_per_pair <= max_memory`` (at least 1 x 1)."""
    if max_memory <= 0:
        raise ValueError(f"max_memory: expected a positive number of bytes, found {max_memory}")
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
    """
    if not (extent > 0 and math.isfinite(extent)):
        return None
    exponent = math.frexp(extent)[1]
    limit = math.frexp(torch.finfo(dtype).max)[1] // (2 * degree)
    return None if -limit <= exponent <= limit else math.ldexp(1.0, -exponent)


def check_representable(dists: Tensor, name: str) -> None:
    """Raise when finite inputs gave non-finite distances: the dtype cannot hold them (e.g. float32 beyond ~1e19)."""
    if dists.numel() and not bool(torch.isfinite(dists.detach()).all()):
        raise NonFiniteError(
            f"{name}: the distances overflow {dists.dtype} (coordinates too large for its range, "
            f"max {torch.finfo(dists.dtype).max:.3g}); compute in float64"
        )


def extreme_range(points: Tensor, ref: Tensor, degree: int) -> tuple[Tensor, float] | None:
    """``(centre, scale)`` when coordinates need exact power-of-two scaling (:func:`range_scale`), else ``None``.

    The extent is measured about the bounding-box centre of ``ref`` (all items together), so a small mesh far from
    the origin is not scaled while a mesh of extreme size (or with extremely far query points) is. Callers compute on
    ``(x - centre) * scale`` and map distances back by ``/ scale`` (closest points by ``/ scale + centre``).
    """
    if points.numel() == 0 or ref.numel() == 0:
        return None
    with torch.no_grad():
        lo, hi = ref.detach().aminmax(dim=0)
        centre = 0.5 * (lo + hi)
        extent = float(torch.cat([points.detach() - centre, ref.detach() - centre]).abs().amax())
    scale = range_scale(extent, ref.dtype, degree)
    return None if scale is None or not all(map(math.isfinite, centre.tolist())) else (centre, scale)
