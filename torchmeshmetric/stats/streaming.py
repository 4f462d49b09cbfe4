"""A streaming, mergeable accumulator of distance sets (plain Python object, no torchmetrics needed)."""

from __future__ import annotations

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, NonFiniteError, check_shape
from torchmeshmetric.stats.moments import Moments, merge_moments, moments_of
from torchmeshmetric.stats.sketch import QuantileSketch
from torchmeshmetric.stats.statistics import (
    QUANTILE_LEVELS,
    DistanceStatistics,
    linear_quantiles,
    statistics_from_parts,
)

__all__ = ["DistanceAccumulator"]


class DistanceAccumulator:
    """Accumulate distances batch by batch (and merge accumulators) into :class:`DistanceStatistics`.

    Keeps, in float64, the count, mean and ``M2`` (merged with Chan et al. 1979's parallel formula), the sum of
    squares, the minimum and the maximum. Quantiles are exact when ``exact_quantiles=True`` (all values are kept,
    ``8 N`` bytes), otherwise estimated by a fixed-size :class:`~torchmeshmetric.stats.sketch.QuantileSketch` whose
    estimates are within relative error ``relative_accuracy`` of the exact order statistics.
    ``compute()`` equals :func:`~torchmeshmetric.stats.distance_statistics` on the concatenated data (to float64
    rounding), whatever the batching or merge order.

    Args:
        exact_quantiles: keep the values for exact quantiles (default) or use the sketch.
        relative_accuracy: the sketch's relative-error bound.

    Example:
        >>> import torch
        >>> acc = DistanceAccumulator()
        >>> _ = acc.update(torch.tensor([1.0, 2.0])).update(torch.tensor([3.0, 4.0]))
        >>> s = acc.compute(peak=10.0)
        >>> s.ave.item(), s.var.item(), s.mse.item(), s.count.item()
        (2.5, 1.25, 7.5, 4)
    """

    def __init__(self, *, exact_quantiles: bool = True, relative_accuracy: float = 1e-3) -> None:
        self.exact_quantiles = bool(exact_quantiles)
        self.sketch = QuantileSketch(relative_accuracy)
        self.reset()

    def reset(self) -> None:
        """Forget everything accumulated."""
        empty = torch.zeros(0, dtype=torch.float64)
        self._moments: Moments = moments_of(empty)
        self._values: list[Tensor] = []
        self._counts: Tensor | None = None

    @property
    def count(self) -> int:
        """Number of distances accumulated."""
        return int(self._moments.count.item())

    @property
    def moments(self) -> Moments:
        """The merged :class:`~torchmeshmetric.stats.moments.Moments` (0-dim float64 fields)."""
        return self._moments

    def update(self, dists: Tensor) -> DistanceAccumulator:
        """Add a ``(N,)`` tensor of distances (``N`` may be 0). Returns ``self``."""
        check_shape(dists, ("N",), "dists")
        d = dists.detach().to(torch.float64)
        if d.numel() == 0:
            return self
        if not bool(torch.isfinite(d).all()):
            raise NonFiniteError(f"dists: expected finite values, found {int((~torch.isfinite(d)).sum())} NaN/Inf")
        self._merge_moments(moments_of(d))
        if self.exact_quantiles:
            self._values.append(d)
        else:
            c = self.sketch.counts(d)
            self._counts = c if self._counts is None else self._counts.to(c.device) + c
        return self

    def merge(self, other: DistanceAccumulator) -> DistanceAccumulator:
        """Add everything ``other`` accumulated (same quantile mode required). Returns ``self``."""
        if other.exact_quantiles != self.exact_quantiles or (
            not self.exact_quantiles and other.sketch.num_bins != self.sketch.num_bins
        ):
            raise ValueError("other: expected an accumulator with the same quantile mode and sketch accuracy")
        self._merge_moments(other._moments)
        self._values.extend(other._values)
        if other._counts is not None:
            self._counts = (
                other._counts.clone() if self._counts is None else self._counts + other._counts.to(self._counts.device)
            )
        return self

    def _merge_moments(self, m: Moments) -> None:
        dev = m.count.device
        rows = Moments(*[torch.stack([a.to(dev), b]) for a, b in zip(self._moments, m, strict=True)])
        self._moments = merge_moments(rows)

    def compute(self, *, ddof: int = 0, peak: float | Tensor | None = None) -> DistanceStatistics:
        """Statistics of everything accumulated (see :func:`~torchmeshmetric.stats.distance_statistics`).

        Raises:
            EmptyInputError: nothing was accumulated.
        """
        if self.count == 0:
            raise EmptyInputError("DistanceAccumulator.compute: no distances were accumulated")
        m = self._moments
        if self.exact_quantiles:
            dev = m.count.device
            qv = linear_quantiles(torch.cat([v.to(dev) for v in self._values]), QUANTILE_LEVELS)
        else:
            assert self._counts is not None
            q = torch.tensor(QUANTILE_LEVELS, dtype=torch.float64, device=self._counts.device)
            qv = self.sketch.quantile(self._counts, q, m.min, m.max)
        return statistics_from_parts(m, qv, ddof=ddof, peak=peak)
