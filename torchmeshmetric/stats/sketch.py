r"""Fixed-size, mergeable quantile sketch with a relative-error bound (log-bucket histogram, DDSketch).

Masson, Rim & Lee (2019), *DDSketch: A Fast and Fully-Mergeable Quantile Sketch with Relative-Error
Guarantees*. A non-negative value ``x`` in ``[min_value, max_value]`` falls in bucket ``i = ceil(log_gamma x)``
with :math:`\gamma = (1 + \alpha) / (1 - \alpha)`; bucket ``i`` covers :math:`(\gamma^{i-1}, \gamma^i]` and is
represented by :math:`2 \gamma^i / (\gamma + 1)`, which is within relative error :math:`\alpha` of every value of
the bucket. Counts are a fixed-length vector, so two sketches merge by addition (a ``dist_reduce_fx="sum"`` state).

Guarantee (tested): for a quantile ``q``, the estimate of the order statistic of rank ``r`` (0-based) is within
relative error ``alpha`` of the exact ``r``-th smallest value, when that value lies in ``[min_value, max_value]``.
Values below ``min_value`` (including exact zeros) share one *zero bucket* represented by 0 (absolute error
``< min_value``); values above ``max_value`` go to the last bucket. Estimates are clamped to the exact
``[min, max]`` of the data. :meth:`QuantileSketch.quantile` interpolates linearly between ranks like
``numpy.percentile(..., method="linear")``; a convex combination of two estimates each within ``alpha`` of its
order statistic is within ``alpha`` of the interpolated exact value, so the bound carries over.

The window ``[min_value, max_value]`` is fixed, so that count vectors merge by addition (streaming, DDP). Where the
values are all at hand (:meth:`QuantileSketch.quantiles_of`, the one-shot ``distance_statistics``), the window
follows the data: values whose mean is below ``1e6 * min_value`` or whose maximum exceeds ``max_value`` are
counted in a power-of-two unit near their mean (exact, divided back), so the bound holds at any scale (until review
V, distances around 1e13 got every quantile = 1e12 and around 1e-13 the minimum). Where counts were made in the
fixed window, :meth:`QuantileSketch.quantile` warns (:class:`SketchRangeWarning`) when a reported quantile comes
from the zero bucket while every value is positive, or from the last bucket while the maximum exceeds
``max_value``: that estimate has no relative-error bound.
"""

from __future__ import annotations

import math
import warnings

import torch
from torch import Tensor

__all__ = ["QuantileSketch", "SketchRangeWarning"]


class SketchRangeWarning(UserWarning):
    """A sketched quantile lies outside the sketch's window ``[min_value, max_value]``: no relative-error bound.

    Example:
        >>> import torch, warnings
        >>> sketch = QuantileSketch(relative_accuracy=0.01, min_value=1e-3, max_value=10.0)
        >>> x = torch.tensor([100.0, 200.0, 300.0], dtype=torch.float64)  # above the window
        >>> with warnings.catch_warnings(record=True) as caught:
        ...     warnings.simplefilter("always")
        ...     _ = sketch.quantile(sketch.counts(x), torch.tensor([0.5]), x.min(), x.max())
        >>> len(caught), caught[0].category.__name__
        (1, 'SketchRangeWarning')
    """


class QuantileSketch:
    """Configuration and operations of a log-bucket quantile sketch (the counts live outside, as a tensor).

    Args:
        relative_accuracy: ``alpha`` in ``(0, 1)``, the relative-error bound (default ``1e-3``, i.e. 0.1 %).
        min_value: smallest value resolved with relative error; smaller ones go to the zero bucket.
        max_value: largest value resolved with relative error.

    Attributes:
        num_bins: length of the count vector (zero bucket first).

    Example:
        >>> import torch
        >>> sk = QuantileSketch(relative_accuracy=0.01)
        >>> x = torch.arange(1, 1001, dtype=torch.float64)
        >>> counts = sk.counts(x)
        >>> est = sk.quantile(counts, torch.tensor([0.5]), x.min(), x.max())
        >>> abs(est.item() - 500.5) / 500.5 <= 0.01
        True
    """

    def __init__(self, relative_accuracy: float = 1e-3, min_value: float = 1e-12, max_value: float = 1e12) -> None:
        if not 0.0 < relative_accuracy < 1.0:
            raise ValueError(f"relative_accuracy: expected a value in (0, 1), found {relative_accuracy}")
        if not 0.0 < min_value < max_value:
            raise ValueError(f"min_value/max_value: expected 0 < min_value < max_value, found {min_value}, {max_value}")
        self.relative_accuracy = float(relative_accuracy)
        self.min_value = float(min_value)
        self.max_value = float(max_value)
        self.gamma = (1.0 + relative_accuracy) / (1.0 - relative_accuracy)
        self._log_gamma = math.log1p(2.0 * relative_accuracy / (1.0 - relative_accuracy))
        self._lo = math.ceil(math.log(min_value) / self._log_gamma)
        self._hi = math.ceil(math.log(max_value) / self._log_gamma)
        self.num_bins = self._hi - self._lo + 2

    def __repr__(self) -> str:
        return (
            f"QuantileSketch(relative_accuracy={self.relative_accuracy}, min_value={self.min_value}, "
            f"max_value={self.max_value}, num_bins={self.num_bins})"
        )

    def bin_index(self, values: Tensor) -> Tensor:
        """``(N,)`` bucket of each value (0 = zero bucket)."""
        x = values.detach().reshape(-1).to(torch.float64)
        i = torch.ceil(torch.log(x.clamp_min(self.min_value)) / self._log_gamma).clamp(self._lo, self._hi)
        idx = (i - self._lo + 1).long()
        return torch.where(x < self.min_value, torch.zeros_like(idx), idx)

    def counts(self, values: Tensor) -> Tensor:
        """``(num_bins,)`` float64 bucket counts of ``values`` (add count vectors to merge)."""
        out = torch.zeros(self.num_bins, dtype=torch.float64, device=values.device)
        return out.index_add_(0, self.bin_index(values), torch.ones_like(values.reshape(-1), dtype=torch.float64))

    def bin_value(self, idx: Tensor) -> Tensor:
        """Representative value of buckets ``idx`` (0 for the zero bucket)."""
        i = (idx.to(torch.float64) - 1 + self._lo).clamp(min=self._lo)
        rep = 2.0 * torch.exp(i * self._log_gamma) / (self.gamma + 1.0)
        return torch.where(idx == 0, torch.zeros_like(rep), rep)

    def quantile(self, counts: Tensor, q: Tensor, vmin: Tensor, vmax: Tensor) -> Tensor:
        """Estimated quantiles (linear interpolation between order statistics, as ``numpy.percentile``).

        Args:
            counts: ``(num_bins,)`` bucket counts.
            q: ``(Q,)`` quantile levels in ``[0, 1]``.
            vmin: exact minimum of the data (0-dim), used to clamp the estimates.
            vmax: exact maximum of the data (0-dim).

        Returns:
            ``(Q,)`` float64 estimates; NaN when the sketch is empty.
        """
        c = counts.to(torch.float64)
        total = c.sum()
        q = q.to(device=c.device, dtype=torch.float64)
        if float(total) <= 0:
            return torch.full_like(q, float("nan"))
        cum = c.cumsum(0)
        pos = q * (total - 1)
        lo_rank, hi_rank = torch.floor(pos), torch.ceil(pos)
        frac = pos - lo_rank

        def order_stat(rank: Tensor) -> Tensor:
            # Bucket holding the value of 0-based rank r: first bucket whose cumulative count exceeds r.
            idx = torch.searchsorted(cum, rank, right=True).clamp(max=self.num_bins - 1)
            return self.bin_value(idx).clamp(vmin.to(c), vmax.to(c))

        lo_v, hi_v = order_stat(lo_rank), order_stat(hi_rank)
        self._warn_outside(cum, torch.cat([lo_rank, hi_rank]), vmin, vmax)
        return lo_v + frac * (hi_v - lo_v)

    def _warn_outside(self, cum: Tensor, ranks: Tensor, vmin: Tensor, vmax: Tensor) -> None:
        """Warn when an order statistic used comes from a bucket without the relative bound (see the module)."""
        idx = torch.searchsorted(cum, ranks, right=True).clamp(max=self.num_bins - 1)
        low = float(vmin) > 0 and bool((idx == 0).any())
        high = float(vmax) > self.max_value and bool((idx == self.num_bins - 1).any())
        if low or high:
            where = f"below min_value={self.min_value:g}" if low else f"above max_value={self.max_value:g}"
            warnings.warn(
                f"quantile sketch: a reported quantile lies {where} (data in [{float(vmin):.3g}, {float(vmax):.3g}]), "
                f"so it is not within relative error {self.relative_accuracy:g}; use exact quantiles, or distances "
                "in a unit that brings them into the window",
                SketchRangeWarning,
                stacklevel=3,
            )

    def unit_exponent(self, mean: float, vmax: float) -> int | None:
        """Exponent ``k``: values of ``mean`` and maximum ``vmax`` are counted times ``2**k``; ``None``: as they are.

        They are counted as they are when the window fits them: ``vmax <= max_value`` and ``mean >= 1e6 *
        min_value`` (values down to a millionth of their mean are resolved). Otherwise ``2**k`` brings ``mean`` into
        ``[0.5, 1)``: values from ~``1e-12`` to ~``1e12`` times the mean are resolved (the maximum of ``N < 1e12``
        values is below ``N`` times their mean). ``k`` may exceed float64's exponent range (subnormal means); it is
        applied in two steps.

        Example:
            >>> sk = QuantileSketch()
            >>> sk.unit_exponent(0.5, 2.0) is None, sk.unit_exponent(4.8e12, 9.9e12)
            (True, -43)
        """
        if vmax <= self.max_value and mean >= 1e6 * self.min_value:
            return None
        if not (mean > 0 and math.isfinite(mean)):
            return None
        return -math.frexp(mean)[1]

    def quantiles_of(self, values: Tensor, q: Tensor) -> Tensor:
        """Estimated quantiles of ``values`` at hand, in a window that follows them (:meth:`unit_exponent`).

        Args:
            values: ``(N,)`` non-negative finite values (``N`` may be 0).
            q: ``(Q,)`` quantile levels in ``[0, 1]``.

        Returns:
            ``(Q,)`` float64 estimates within relative error ``relative_accuracy`` of the exact ones (values below
            ~``1e-12`` of the mean excepted: absolute error below that); NaN for no values.

        Example:
            >>> import torch
            >>> x = torch.arange(1, 1001, dtype=torch.float64) * 1e13  # beyond the fixed window
            >>> est = QuantileSketch(0.01).quantiles_of(x, torch.tensor([0.5]))
            >>> abs(est.item() - 500.5e13) / 500.5e13 <= 0.01
            True
        """
        x = values.detach().reshape(-1).to(torch.float64)
        if x.numel() == 0:
            return torch.full_like(q, float("nan"), dtype=torch.float64, device=x.device)
        vmin, vmax = x.amin(), x.amax()
        k = self.unit_exponent(float(x.mean()), float(vmax))
        if k is None:
            return self.quantile(self.counts(x), q, vmin, vmax)
        # Powers of two scale exactly (values taken into subnormals lie ~1e300 below the mean: the zero bucket).
        est = self.quantile(self.counts(_ldexp(x, k)), q, _ldexp(vmin, k), _ldexp(vmax, k))
        return _ldexp(est, -k)


def _ldexp(x: Tensor, k: int) -> Tensor:
    """``x * 2**k`` in two steps, so that neither factor overflows float64 (``k`` up to about +-2000)."""
    return x * math.ldexp(1.0, k // 2) * math.ldexp(1.0, k - k // 2)
