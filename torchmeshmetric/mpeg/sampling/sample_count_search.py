"""mmetric's sample-count search (``mm sample --nbSamplesMin N --nbSamplesMax M [--maxIterations K]``).

mmetric samples once with a start value, then, while the point count is outside ``[N, M]`` and fewer than ``K``
(10) refinements were made, moves a bracket and samples again:

* a *resolution* (``face`` mode, integer, start 1024, more points as it grows): too few points -> the lower bound is
  the value and the value doubles (or goes half way to the upper bound once there is one); too many -> the upper
  bound is the value and the value goes half way down to the lower bound (integer halving);
* a *threshold* (``sdiv``'s area threshold and ``ediv``'s edge length threshold, float32, start 1.0, fewer points as
  it grows): the mirror image, in float32 arithmetic.

The result is the last sampling, even when the count is still outside the range after ``K`` refinements (mmetric
writes it all the same), with the value that produced it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal, NamedTuple

import numpy as np

from torchmeshmetric.mpeg.core.point_cloud import PointCloud

__all__ = ["CountSearch", "search_sample_count"]


class CountSearch(NamedTuple):
    """The outcome of :func:`search_sample_count`.

    Attributes:
        cloud: the last sampling.
        value: the resolution or threshold that gave it (mmetric's ``computedResolution`` / ``computedThreshold``).
        iterations: refinements made (mmetric's "algorithm ended after N iterations").
        earlier_points: points of the samplings before the last. mmetric's ``Model::reset`` between samplings
            keeps the colours, so its output file has colours only when this is 0 (the PLY writer drops colours
            whose count differs from the points').
    """

    cloud: PointCloud
    value: float
    iterations: int
    earlier_points: int = 0


def _next_resolution(count: int, lo: int, hi: int, value: int, n_min: int, n_max: int) -> tuple[int, int, int]:
    if count < n_min:  # too few points: a finer resolution
        lo = value
        value = lo * 2 if hi == 0 else lo + (hi - lo) // 2
    if count > n_max:
        hi = value
        value = lo + (hi - lo) // 2
    return lo, hi, value


def _next_threshold(
    count: int, lo: np.float32, hi: np.float32, value: np.float32, n_min: int, n_max: int
) -> tuple[np.float32, np.float32, np.float32]:
    two = np.float32(2)
    if count > n_min:  # mmetric's test: more than the minimum -> a larger threshold, fewer points
        lo = value
        value = lo * two if hi == 0 else np.float32(lo + (hi - lo) / two)
    if count < n_max:
        hi = value
        value = np.float32(lo + (hi - lo) / two)
    return lo, hi, value


def search_sample_count(
    sample: Callable[[float], PointCloud],
    kind: Literal["resolution", "threshold"],
    num_samples_min: int,
    num_samples_max: int,
    max_iterations: int = 10,
) -> CountSearch:
    """Resample until the point count is in ``[num_samples_min, num_samples_max]``, as mmetric searches.

    Args:
        sample: the sampling as a function of the searched value (a resolution or a threshold).
        kind: ``"resolution"`` (``face``: an integer that adds points as it grows, start 1024) or ``"threshold"``
            (``sdiv`` area / ``ediv`` length: a float32 that removes points as it grows, start 1.0).
        num_samples_min: mmetric's ``--nbSamplesMin`` (> 0).
        num_samples_max: ``--nbSamplesMax`` (> ``num_samples_min``).
        max_iterations: ``--maxIterations`` (10).

    Returns:
        :class:`CountSearch`.

    Raises:
        ValueError: ``num_samples_min`` < 1 or ``num_samples_max`` <= ``num_samples_min`` (mmetric refuses the
            latter too), or ``max_iterations`` < 0.

    Example:
        >>> import torch
        >>> def grid(resolution: float) -> PointCloud:  # a stand-in: resolution^2 points
        ...     return PointCloud(torch.zeros(int(resolution) ** 2, 3))
        >>> r = search_sample_count(grid, "resolution", 300_000, 400_000)
        >>> r.value, r.cloud.num_points, r.iterations
        (576, 331776, 4)
    """
    if num_samples_min < 1 or num_samples_max <= num_samples_min:
        raise ValueError(
            f"num_samples_min, num_samples_max: expected 1 <= min < max, found {num_samples_min}, {num_samples_max}"
        )
    if max_iterations < 0:
        raise ValueError(f"max_iterations: expected >= 0, found {max_iterations}")
    if kind == "resolution":
        value: float = 1024
        cloud = sample(value)
        lo_r = hi_r = 0
        it = earlier = 0
        while not num_samples_min <= cloud.num_points <= num_samples_max and it < max_iterations:
            it += 1
            earlier += cloud.num_points
            lo_r, hi_r, res = _next_resolution(
                cloud.num_points, lo_r, hi_r, int(value), num_samples_min, num_samples_max
            )
            value = res
            cloud = sample(value)
        return CountSearch(cloud, value, it, earlier)
    if kind != "threshold":
        raise ValueError(f"kind: expected 'resolution' or 'threshold', found {kind!r}")
    v = np.float32(1.0)
    cloud = sample(float(v))
    lo = hi = np.float32(0)
    it = earlier = 0
    while not num_samples_min <= cloud.num_points <= num_samples_max and it < max_iterations:
        it += 1
        earlier += cloud.num_points
        lo, hi, v = _next_threshold(cloud.num_points, lo, hi, v, num_samples_min, num_samples_max)
        cloud = sample(float(v))
    return CountSearch(cloud, float(v), it, earlier)
