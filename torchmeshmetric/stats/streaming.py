"""A streaming, mergeable accumulator of distance sets (plain Python object, no torchmetrics needed)."""

from __future__ import annotations

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, check_flag
from torchmeshmetric.stats.moments import Moments, merge_into_row, moments_of, moments_rows
from torchmeshmetric.stats.sketch import QuantileSketch
from torchmeshmetric.stats.statistics import (
    DistanceStatistics,
    distance_statistics_compute,
    distance_statistics_update,
)

__all__ = ["DistanceAccumulator"]


class DistanceAccumulator:
    """Accumulate distances batch by batch (and merge accumulators) into :class:`DistanceStatistics`.

    Keeps, in float64, the count, mean and ``M2`` (merged with Chan et al. 1979's parallel formula), the sum of
    squares, the minimum and the maximum. Quantiles are exact when ``exact_quantiles=True`` (all values are kept,
    ``8 N`` bytes), otherwise estimated by a fixed-size :class:`~torchmeshmetric.stats.sketch.QuantileSketch` whose
    estimates are within relative error ``relative_accuracy`` of the exact order statistics that lie in its fixed
    window ``[1e-12, 1e12]`` (fixed so that accumulators merge by adding counts; a quantile outside it raises a
    :class:`~torchmeshmetric.stats.sketch.SketchRangeWarning`: express the distances in a unit that brings them
    into the window, or keep exact quantiles; the one-shot ``distance_statistics`` has no such window).
    ``compute()`` equals :func:`~torchmeshmetric.stats.distance_statistics` on the concatenated data (to float64
    rounding), whatever the batching or merge order: every batch passes through the same checks and sufficient
    statistics (``distance_statistics_update``) and the result is finished by the same ``distance_statistics_compute``
    as that function and the ``torchmetrics`` metrics.

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
        exact_quantiles = check_flag(exact_quantiles, "exact_quantiles")
        self.exact_quantiles = bool(exact_quantiles)
        self.sketch = QuantileSketch(relative_accuracy)
        self.reset()

    def reset(self) -> None:
        """Forget everything accumulated."""
        # One (1, 6) row of merged moments, starting from the empty (neutral) summary.
        self._row: Tensor = moments_rows(moments_of(torch.zeros(0, dtype=torch.float64)))
        self._values: list[Tensor] = []
        self._counts: Tensor | None = None

    @property
    def _sketch(self) -> QuantileSketch | None:
        return None if self.exact_quantiles else self.sketch

    @property
    def count(self) -> int:
        """Number of distances accumulated."""
        return int(self._row[0, 0].item())

    @property
    def moments(self) -> Moments:
        """The merged :class:`~torchmeshmetric.stats.moments.Moments` (0-dim float64 fields)."""
        return Moments(*self._row[0])

    def update(self, dists: Tensor) -> DistanceAccumulator:
        """Add a ``(N,)`` tensor of distances (``N`` may be 0). Returns ``self``."""
        moments, quantile_data = distance_statistics_update(dists, self._sketch)
        if dists.numel() == 0:
            return self
        if self._sketch is None:
            self._add(moments, [quantile_data], None)
        else:
            self._add(moments, [], quantile_data)
        return self

    def merge(self, other: DistanceAccumulator) -> DistanceAccumulator:
        """Add everything ``other`` accumulated (same quantile mode required). Returns ``self``."""
        if other.exact_quantiles != self.exact_quantiles or (
            not self.exact_quantiles and other.sketch.num_bins != self.sketch.num_bins
        ):
            raise ValueError("other: expected an accumulator with the same quantile mode and sketch accuracy")
        self._add(other.moments, other._values, other._counts)
        return self

    def _add(self, moments: Moments, values: list[Tensor], counts: Tensor | None) -> None:
        self._row = merge_into_row(self._row.to(moments.count.device), moments)
        self._values.extend(values)
        if counts is not None:
            self._counts = counts.clone() if self._counts is None else self._counts + counts.to(self._counts.device)

    def compute(self, *, ddof: int = 0, peak: float | Tensor | None = None) -> DistanceStatistics:
        """Statistics of everything accumulated (see :func:`~torchmeshmetric.stats.distance_statistics`).

        Raises:
            EmptyInputError: nothing was accumulated.
        """
        if self.count == 0:
            raise EmptyInputError(
                "DistanceAccumulator.compute: no distances were accumulated; call update() with non-empty distances "
                "first"
            )
        m = self.moments
        if self._sketch is None:
            quantile_data = torch.cat([v.to(m.count.device) for v in self._values])
        else:
            assert self._counts is not None
            quantile_data = self._counts
        return distance_statistics_compute(m, quantile_data, sketch=self._sketch, ddof=ddof, peak=peak)
