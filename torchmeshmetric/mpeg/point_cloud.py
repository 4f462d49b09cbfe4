"""The point clouds mmetric compares, and its duplicate-point rule (``dropDuplicates=2``: average)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric import native
from torchmeshmetric._checks import EmptyInputError, check_finite, check_shape

__all__ = ["PointCloud", "merge_duplicate_points"]


@dataclass(frozen=True, eq=False)
class PointCloud:
    """A sampled point cloud as mmetric holds it: float32 positions, optional normals and colours.

    Args:
        points: ``(N, 3)`` positions (float32, as mmetric stores them).
        normals: ``(N, 3)`` normals (float32) or ``None``.
        colors: ``(N, 3)`` RGB colours in ``[0, 255]`` (float32, before mmetric rounds them to 8 bits) or ``None``.

    Example:
        >>> import torch
        >>> PointCloud(torch.zeros(2, 3)).num_points
        2
    """

    points: Tensor
    normals: Tensor | None = None
    colors: Tensor | None = None

    def __post_init__(self) -> None:
        check_shape(self.points, ("N", 3), "points")
        check_finite(self.points, "points")
        for name in ("normals", "colors"):
            value = getattr(self, name)
            if value is not None:
                check_shape(value, (self.points.shape[0], 3), name)

    @property
    def num_points(self) -> int:
        """Number of points ``N``."""
        return int(self.points.shape[0])


def _merge_order(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points sorted by (x, y, z) then original index (std::sort with mmetric's comparator), and each run's start."""
    ext = native.try_load("pcc")
    if ext is not None:
        order_t, starts_t = ext.mpeg_merge_order(torch.from_numpy(pts))
        return order_t.numpy(), starts_t.numpy()
    # no C++ compiler: the same order through numpy (a few times slower)
    order = np.lexsort((np.arange(pts.shape[0]), pts[:, 2], pts[:, 1], pts[:, 0]))
    spts = pts[order]
    new = np.ones(spts.shape[0], dtype=bool)
    new[1:] = np.any(spts[1:] != spts[:-1], axis=1)
    return order, np.flatnonzero(new)


def _sequential_sums(values: np.ndarray, starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Each run's float32 sum, added one value at a time from its first as mmetric's loop adds them.

    ``np.add.reduceat`` may add in another order (pairwise, unrolled), and float32 sums depend on the order: merged
    normals one ulp off moved mesh-mode D2 in the 9th digit (sphere / sphere_qp8: 66.4773219 against mm's
    66.4773218). The loop runs once per position within the runs, over the runs that long.
    """
    acc = values[starts].copy()
    for k in range(1, int(counts.max()) if counts.size else 0):
        sel = np.flatnonzero(counts > k)
        acc[sel] += values[starts[sel] + k]
    return acc


def merge_duplicate_points(cloud: PointCloud, name: str = "cloud") -> PointCloud:
    """Merge points with equal coordinates as mmetric's ``compare --mode pcc`` does before measuring.

    The cloud is sorted by ``(x, y, z)`` (ties by index); each run of equal positions becomes one point whose normal is
    the float32 mean of the run's normals (not renormalised) and whose colour is the integer mean (truncated) of the
    colours rounded to 8 bits. ``-0.0`` and ``0.0`` are the same coordinate.

    Args:
        cloud: the cloud to merge.
        name: the cloud's name in the error message (``"ref"``, ``"dis"``).

    Returns:
        The merged cloud, sorted by position; colours are returned as integers in ``[0, 255]`` (float32).

    Raises:
        EmptyInputError: the cloud has no point.

    Example:
        >>> import torch
        >>> pc = PointCloud(torch.tensor([[1.0, 0, 0], [0, 0, 0], [1, 0, 0]]),
        ...                 normals=torch.tensor([[0.0, 0, 1], [0, 1, 0], [1, 0, 0]]))
        >>> m = merge_duplicate_points(pc)
        >>> m.points.tolist(), m.normals.tolist()
        ([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0], [0.5, 0.0, 0.5]])
    """
    if cloud.num_points == 0:
        raise EmptyInputError(f"{name}: expected at least one point, found an empty point cloud")
    pts = np.ascontiguousarray(cloud.points.detach().cpu().numpy(), dtype=np.float32)
    order, starts = _merge_order(pts)
    counts = np.diff(np.append(starts, pts.shape[0]))
    normals = colors = None
    if cloud.normals is not None:
        n = cloud.normals.detach().cpu().numpy().astype(np.float32, copy=False)[order]
        sums = _sequential_sums(n, starts, counts)
        normals = torch.from_numpy((sums / counts.astype(np.float32)[:, None]).astype(np.float32))
    if cloud.colors is not None:
        c = cloud.colors.detach().cpu().numpy().astype(np.float32, copy=False)[order]
        c8 = np.floor(c.astype(np.float64) + 0.5).clip(0, 255).astype(np.int64)  # roundf, then unsigned char
        csum = np.add.reduceat(c8, starts, axis=0)
        colors = torch.from_numpy((csum // counts[:, None]).astype(np.float32))
    return PointCloud(torch.from_numpy(pts[order[starts]]), normals, colors)
