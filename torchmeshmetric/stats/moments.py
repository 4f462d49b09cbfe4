r"""Mergeable first and second moments of distance sets (Chan, Golub & LeVeque 1979).

A distance set is summarised by ``Moments(count, mean, m2, sumsq, min, max)`` in float64, where ``m2`` is the
sum of squared deviations from the mean. Partial summaries of disjoint parts combine exactly (up to float64
rounding) with Chan et al.'s parallel formula

.. math::

    n = n_a + n_b,\quad \delta = \bar x_b - \bar x_a,\quad
    \bar x = \bar x_a + \delta\, n_b / n,\quad M_2 = M_{2,a} + M_{2,b} + \delta^2\, n_a n_b / n,

and, for ``K`` parts at once, the same shift form from the largest part ``r``:
:math:`\bar x = \bar x_r + \sum_k n_k (\bar x_k - \bar x_r) / n`,
:math:`M_2 = \sum_k M_{2,k} + \sum_k n_k (\bar x_k - \bar x)^2`. Nothing is computed as
:math:`E[x^2] - E[x]^2`, so float32 distances with large offsets lose no precision to cancellation. A set's own mean
is likewise its minimum plus the mean of the shifts from it, so a constant set (or stream, however it is batched)
has its value as mean and ``m2 = 0`` exactly; a stream of ``U`` merges accumulates about ``sqrt(U)`` roundings of
the mean (20 000 single-value updates of uniform data: 3e-15 relative). Values so large that a sum of them
overflows (near 1.7e308) are summed scaled by an exact power of two (each set of a batch by its own): the mean and
``m2`` overflow only where their true values do (``m2`` and ``sumsq`` for values beyond ~1e154; the statistics then
take ``rmse`` and ``std`` from the values, see ``statistics_from_parts``).
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import IndexRangeError, check_int
from torchmeshmetric.structures import batch_index, power_of_two_scale_down

__all__ = ["Moments", "merge_into_row", "merge_mean_m2", "merge_moments", "merge_rows", "moments_of", "moments_rows"]


class Moments(NamedTuple):
    r"""Sufficient statistics of one or several distance sets (float64; 0-dim for one set, ``(B,)`` per item).

    Attributes:
        count: number of values (float64 so that it merges like the other fields).
        mean: arithmetic mean (``0`` when ``count == 0``).
        m2: sum of squared deviations from ``mean``.
        sumsq: sum of squared values, :math:`\sum d^2` (no cancellation: every term is non-negative for
            distances).
        min: smallest value (``+inf`` when empty).
        max: largest value (``-inf`` when empty).

    Example:
        >>> import torch
        >>> m = moments_of(torch.tensor([1.0, 2.0, 3.0, 4.0]))
        >>> m.count.item(), m.mean.item(), m.m2.item(), m.sumsq.item(), m.min.item(), m.max.item()
        (4.0, 2.5, 5.0, 30.0, 1.0, 4.0)
        >>> halves = moments_of(torch.tensor([1.0, 2.0, 3.0, 4.0]), torch.tensor([2, 2]))  # (B,) per item, merged
        >>> merge_moments(halves).m2.item()
        5.0
    """

    count: Tensor  # type: ignore[assignment]  # shadows tuple.count on purpose (the statistic's name)
    mean: Tensor
    m2: Tensor
    sumsq: Tensor
    min: Tensor
    max: Tensor


def moments_of(values: Tensor, lengths: Tensor | None = None) -> Moments:
    """Two-pass moments of a set (or of every item of a packed ragged batch) in float64.

    Args:
        values: ``(N,)`` values, or packed ``(sum N_b,)`` with ``lengths``.
        lengths: optional ``(B,)`` items sizes; gives ``(B,)`` fields, else 0-dim fields.

    Returns:
        :class:`Moments`; empty sets have ``count = 0``, ``mean = m2 = sumsq = 0``, ``min = +inf``, ``max = -inf``.

    Example:
        >>> import torch
        >>> m = moments_of(torch.tensor([1.0, 2.0, 3.0]))
        >>> m.count.item(), m.mean.item(), m.m2.item(), m.sumsq.item()
        (3.0, 2.0, 2.0, 14.0)
    """
    x = values.detach().reshape(-1).to(torch.float64)
    if lengths is None:
        n = x.new_tensor(float(x.numel()))
        if x.numel() == 0:
            z = x.new_zeros(())
            return Moments(n, z, z.clone(), z.clone(), x.new_tensor(float("inf")), x.new_tensor(float("-inf")))
        lo, hi = x.aminmax()
        mean, m2 = _mean_m2(x, lo, n)
        return Moments(n, mean, m2, (x * x).sum(), lo, hi)
    num = int(lengths.numel())
    b = batch_index(lengths.to(device=x.device, dtype=torch.long))
    n = lengths.to(device=x.device, dtype=torch.float64)
    lo = x.new_full((num,), float("inf")).scatter_reduce(0, b, x, reduce="amin")
    hi = x.new_full((num,), float("-inf")).scatter_reduce(0, b, x, reduce="amax")
    mean, m2 = _mean_m2(x, lo, n, b)
    sumsq = x.new_zeros(num).index_add_(0, b, x * x)
    return Moments(n, mean, m2, sumsq, lo, hi)


def _mean_m2(x: Tensor, lo: Tensor, n: Tensor, batch: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """Two-pass ``(mean, m2)`` of the values ``x`` of one set (``batch=None``) or of ``(B,)`` sets, ``lo`` their minima.

    ``mean = lo + sum(x - lo) / n``: exact for a constant set. Where a sum overflows although the values are finite
    (values near 1.7e308), both passes are redone on ``x`` scaled by an exact power of two (one check of the results;
    the usual case pays nothing else). Empty sets get ``mean = m2 = 0``.
    """

    def passes(v: Tensor, low: Tensor) -> tuple[Tensor, Tensor]:
        if batch is None:
            mean = low + (v - low).sum() / n
            return mean, ((v - mean) ** 2).sum()
        has = n > 0
        low = torch.where(has, low, torch.zeros_like(low))
        mean = low + v.new_zeros(n.shape).index_add_(0, batch, v - low[batch]) / n.clamp_min(1.0)
        return mean, v.new_zeros(n.shape).index_add_(0, batch, (v - mean[batch]) ** 2)

    mean, m2 = passes(x, lo)
    finite = torch.isfinite(mean) & torch.isfinite(m2)
    if bool(finite.all()):
        return mean, m2
    # Each set by its own power of two (|x| * scale in [0.5, 1): exact), and only the sets that overflowed take the
    # redone figures: one scale for a whole batch underflowed a small item's deviations (its var came out 0/0).
    if batch is None:
        scale = power_of_two_scale_down(x.abs().amax())
    else:
        big = x.new_zeros(n.shape).scatter_reduce(0, batch, x.abs(), reduce="amax")
        scale = power_of_two_scale_down(big)
    mean_s, m2_s = passes(x * (scale if batch is None else scale[batch]), lo * scale)
    # m2 is divided by the scale twice: scale * scale underflows to 0 for values beyond ~1e162.
    return torch.where(finite, mean, mean_s / scale), torch.where(finite, m2, m2_s / scale / scale)


def merge_moments(parts: Moments, dim: int = 0) -> Moments:
    """Merge ``K`` partial summaries stacked along ``dim`` into one (Chan et al. 1979, generalised to K parts).

    Args:
        parts: :class:`Moments` whose fields have a ``K`` dimension at ``dim`` (e.g. ``(K,)`` rows gathered from
            several batches or processes). Parts with ``count = 0`` are neutral.
        dim: the dimension to merge over.

    Returns:
        :class:`Moments` with ``dim`` removed; equal (to float64 rounding) to :func:`moments_of` on the union.

    Raises:
        IndexRangeError: ``dim`` is not a dimension of the fields.

    Example:
        >>> import torch
        >>> a, b = moments_of(torch.tensor([1.0, 2.0])), moments_of(torch.tensor([3.0]))
        >>> m = merge_moments(Moments(*[torch.stack([x, y]) for x, y in zip(a, b)]))
        >>> m.count.item(), m.mean.item(), m.m2.item()
        (3.0, 2.0, 2.0)
    """
    ndim = parts.count.dim()
    dim = check_int(dim, "dim")
    if not -ndim <= dim < max(ndim, 1):
        # torch's "Dimension out of range" named no argument (found by review)
        raise IndexRangeError(f"dim: expected a dimension of the parts' {ndim}-D fields, found {dim!r}")
    count, mean, m2, sumsq, lo, hi = (t.to(torch.float64) for t in parts)
    n, new_mean, new_m2 = merge_mean_m2(count, mean, m2, dim)
    if lo.shape[dim] == 0:
        inf = torch.full_like(n, float("inf"))
        return Moments(n, new_mean, new_m2, sumsq.sum(dim), inf, -inf)
    return Moments(n, new_mean, new_m2, sumsq.sum(dim), lo.amin(dim), hi.amax(dim))


def merge_mean_m2(count: Tensor, mean: Tensor, m2: Tensor, dim: int = 0) -> tuple[Tensor, Tensor, Tensor]:
    """Chan et al. merge of ``(count, mean, m2)`` parts along ``dim``; returns the merged ``(count, mean, m2)``."""
    count, mean, m2 = count.to(torch.float64), mean.to(torch.float64), m2.to(torch.float64)
    n = count.sum(dim)
    if count.shape[dim] == 0:
        return n, torch.zeros_like(n), m2.sum(dim)
    # Shift form from the largest part: equal means (a constant stream) merge exactly, and no n_k * mean_k is formed
    # (it rounded the whole mean at every merge, and overflowed for means near 1.7e308).
    ref = mean.gather(dim, count.argmax(dim, keepdim=True))
    shift = torch.where(count > 0, mean - ref, torch.zeros_like(mean))
    new_mean = torch.where(n > 0, ref.squeeze(dim) + (count * shift).sum(dim) / n.clamp_min(1.0), torch.zeros_like(n))
    dev = torch.where(count > 0, mean - new_mean.unsqueeze(dim), torch.zeros_like(mean))
    return n, new_mean, m2.sum(dim) + (count * dev * dev).sum(dim)


def moments_rows(moments: Moments) -> Tensor:
    """``(R, 6)`` float64 rows of :class:`Moments` with ``(R,)`` fields (``(1, 6)`` for 0-dim fields).

    Columns follow the field order ``count, mean, m2, sumsq, min, max``: the form in which a ``torchmetrics`` state
    holds partial moments (one row, reduced by :func:`~torchmeshmetric.metrics.distance_states.merge_moment_rows`).

    Example:
        >>> import torch
        >>> moments_rows(moments_of(torch.tensor([1.0, 3.0]))).tolist()
        [[2.0, 2.0, 2.0, 10.0, 1.0, 3.0]]
    """
    return torch.stack([t.to(torch.float64) for t in moments], dim=-1).reshape(-1, len(Moments._fields))


def merge_rows(rows: Tensor) -> Moments:
    """Merge ``(R, 6)`` rows of partial moments (see :func:`moments_rows`) into 0-dim :class:`Moments`.

    ``R = 0`` gives the empty summary (``count = 0``, ``min = +inf``, ``max = -inf``).

    Example:
        >>> import torch
        >>> rows = torch.cat([moments_rows(moments_of(torch.tensor(x))) for x in ([1.0, 2.0], [3.0])])
        >>> m = merge_rows(rows)
        >>> m.count.item(), m.mean.item(), m.m2.item()
        (3.0, 2.0, 2.0)
    """
    return merge_moments(Moments(*rows.unbind(-1)))


def merge_into_row(rows: Tensor, part: Moments) -> Tensor:
    """Merge the 0-dim moments ``part`` into ``(R, 6)`` rows: one ``(1, 6)`` row, on the device of ``rows``.

    One update of a streaming summary: the rows (none, one, or several after a DDP gather or a ``forward()``) and the
    new part are merged with Chan et al.'s formula, so the state stays one row however many updates it sees.

    Example:
        >>> import torch
        >>> row = merge_into_row(torch.zeros(0, 6, dtype=torch.float64), moments_of(torch.tensor([1.0, 2.0])))
        >>> merge_into_row(row, moments_of(torch.tensor([3.0])))[0, :3].tolist()
        [3.0, 2.0, 2.0]
    """
    return moments_rows(merge_rows(torch.cat([rows, moments_rows(part).to(rows.device)])))
