"""The point clouds mmetric compares, and its duplicate-point rule (``dropDuplicates=2``: average)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric import native
from torchmeshmetric._checks import EmptyInputError, check_finite, check_rgb255, check_shape

__all__ = ["PointCloud", "merge_duplicate_points"]


@dataclass(frozen=True, eq=False)
class PointCloud:
    """A sampled point cloud as mmetric holds it: float32 positions, optional normals, colours and UVs.

    Args:
        points: ``(N, 3)`` positions (float32, as mmetric stores them).
        normals: ``(N, 3)`` normals (float32) or ``None``.
        colors: ``(N, 3)`` RGB colours in ``[0, 255]`` (float32, before mmetric rounds them to 8 bits) or ``None``.
        uvs: ``(N, 2)`` texture coordinates or ``None``: mmetric's samplers keep them for a mesh with UVs and no
            texture map (a map turns them into colours); only its OBJ files show them (``vt`` rows), no figure
            uses them.

    Example:
        >>> import torch
        >>> PointCloud(torch.zeros(2, 3)).num_points
        2
    """

    points: Tensor
    normals: Tensor | None = None
    colors: Tensor | None = None
    uvs: Tensor | None = None

    def __post_init__(self) -> None:
        check_shape(self.points, ("N", 3), "points")
        check_finite(self.points, "points")
        for name in ("normals", "colors"):
            value = getattr(self, name)
            if value is not None:
                check_shape(value, (self.points.shape[0], 3), name)
        if self.uvs is not None:
            check_shape(self.uvs, (self.points.shape[0], 2), "uvs")

    @property
    def num_points(self) -> int:
        """Number of points ``N``."""
        return int(self.points.shape[0])


def _merge_numpy(pts: np.ndarray, cloud: PointCloud) -> PointCloud:
    """The merge through numpy, where the C++ extension cannot be built (a few times slower, the same figures)."""
    order = np.lexsort((np.arange(pts.shape[0]), pts[:, 2], pts[:, 1], pts[:, 0]))
    spts = pts[order]
    new = np.ones(spts.shape[0], dtype=bool)
    new[1:] = np.any(spts[1:] != spts[:-1], axis=1)
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, pts.shape[0]))
    normals = colors = None
    if cloud.normals is not None:
        n = cloud.normals.detach().cpu().numpy().astype(np.float32, copy=False)[order]
        # summed one point at a time in run order, as dmetric's loop (numpy's reduceat sums long runs pairwise)
        sums = np.zeros((starts.shape[0], 3), np.float32)
        for k in range(int(counts.max())):
            live = np.flatnonzero(counts > k)
            sums[live] += n[starts[live] + k]
        normals = torch.from_numpy((sums / counts.astype(np.float32)[:, None]).astype(np.float32))
    if cloud.colors is not None:
        c = cloud.colors.detach().cpu().numpy().astype(np.float32, copy=False)[order]
        c8 = np.nan_to_num(np.floor(c.astype(np.float64) + 0.5), nan=0.0).clip(0, 255).astype(np.int64)
        csum = np.add.reduceat(c8, starts, axis=0)
        colors = torch.from_numpy((csum // counts[:, None]).astype(np.float32))
    return PointCloud(torch.from_numpy(pts[order[starts]]), normals, colors)


def _float32_rows(t: Tensor | None) -> Tensor:
    if t is None:
        return torch.empty(0, 3)
    return t.detach().cpu().to(torch.float32).contiguous()


def merge_duplicate_points(cloud: PointCloud, name: str = "cloud") -> PointCloud:
    """Merge points with equal coordinates as mmetric's ``compare --mode pcc`` does before measuring.

    The cloud is sorted by ``(x, y, z)`` (ties by index); each run of equal positions becomes one point whose normal is
    the float32 mean of the run's normals (not renormalised) and whose colour is the integer mean (truncated) of the
    colours rounded to 8 bits (a NaN colour counts as 0, what mmetric's conversion to 8 bits gives on x86). ``-0.0``
    and ``0.0`` are the same coordinate.

    Args:
        cloud: the cloud to merge.
        name: the cloud's name in the error message (``"ref"``, ``"dis"``).

    Returns:
        The merged cloud, sorted by position; colours are returned as integers in ``[0, 255]`` (float32).

    Raises:
        EmptyInputError: the cloud has no point.
        ValueError: colours outside ``[0, 255]``, or all fractions of ``[0, 1]`` (:func:`check_rgb255`): mmetric
            reads 8-bit colours, and converts wider float values in ways of its own (not a clamp).

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
    if cloud.colors is not None:
        check_rgb255(cloud.colors, f"{name}.colors")
    pts = np.ascontiguousarray(cloud.points.detach().cpu().numpy(), dtype=np.float32)
    ext = native.try_load("pcc")
    if ext is None:
        return _merge_numpy(pts, cloud)
    points, normals, colors = ext.mpeg_merge(torch.from_numpy(pts), _float32_rows(cloud.normals),
                                             _float32_rows(cloud.colors))  # fmt: skip
    return PointCloud(points, None if cloud.normals is None else normals, None if cloud.colors is None else colors)
