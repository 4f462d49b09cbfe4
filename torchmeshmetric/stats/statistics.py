r"""The statistics of a distance set: the paper's five (Section II.C) plus Hausdorff, quantiles and PSNR.

For a distance set :math:`D = \{d_1, \dots, d_n\}` (distances, **not squared**):

.. math::

    \mathrm{Ave} = \frac{1}{n}\sum_i d_i,\qquad
    \mathrm{Var} = \frac{1}{n - \mathrm{ddof}}\sum_i (d_i - \mathrm{Ave})^2,\qquad
    \mathrm{STD} = \sqrt{\mathrm{Var}},

.. math::

    \mathrm{MSE} = \frac{1}{n}\sum_i d_i^2,\qquad \mathrm{RMSE} = \sqrt{\mathrm{MSE}},\qquad
    \mathrm{PSNR} = 10 \log_{10} \frac{\mathrm{peak}^2}{\mathrm{MSE}}\ \text{dB}.

With the default population variance (``ddof=0``), :math:`\mathrm{MSE} = \mathrm{Var} + \mathrm{Ave}^2`, so
:math:`\mathrm{MSE} \ge \mathrm{Ave}^2` always. ``max`` is the one-sided Hausdorff distance. Quantiles
(``median``, ``p95``, ``p99``) use linear interpolation between order statistics (``numpy.percentile``'s
default), exactly or from a :class:`~torchmeshmetric.stats.sketch.QuantileSketch` with a relative-error bound.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import (
    EmptyInputError,
    ShapeError,
    as_real,
    check_finite,
    check_flag,
    check_has_values,
    check_int,
    check_lengths,
    check_real,
    check_shape,
    check_tensor,
)
from torchmeshmetric.stats.moments import Moments, moments_of
from torchmeshmetric.stats.sketch import QuantileSketch
from torchmeshmetric.structures import batch_index, lengths_to_offsets, power_of_two_scale_down

__all__ = [
    "QUANTILE_LEVELS",
    "DistanceStatistics",
    "distance_statistics",
    "distance_statistics_compute",
    "distance_statistics_update",
    "linear_quantiles",
    "psnr_from_mse",
    "statistics_from_parts",
]

QUANTILE_LEVELS = (0.5, 0.95, 0.99)
"""Quantile levels reported as ``median``, ``p95``, ``p99``."""


class DistanceStatistics(NamedTuple):
    """Statistics of a distance set (0-dim float64 tensors) or of each item of a ragged batch (``(B,)``).

    Attributes:
        ave: mean distance (the paper's *Average*).
        var: variance with ``ddof`` (population by default; the paper's *Variance*).
        std: ``sqrt(var)`` (the paper's *Standard Deviation*).
        mse: ``mean(d^2)`` (the paper's *Mean Square Error*; equals ``var + ave^2`` when ``ddof=0``).
        rmse: ``sqrt(mse)`` (the paper's *Root Mean Square Error*).
        max: largest distance (one-sided Hausdorff distance).
        min: smallest distance.
        median: 50 % quantile.
        p95: 95 % quantile.
        p99: 99 % quantile.
        count: number of distances (int64).
        psnr: ``10 log10(peak^2 / mse)`` in dB (``+inf`` when ``mse == 0``), or ``None`` when no peak was given.

    Example:
        >>> import torch
        >>> s = distance_statistics(torch.tensor([1.0, 2.0, 3.0, 4.0]), peak=10.0)
        >>> s.ave.item(), s.var.item(), s.mse.item(), s.max.item(), s.count.item(), round(s.psnr.item(), 4)
        (2.5, 1.25, 7.5, 4.0, 4, 11.2494)
    """

    ave: Tensor
    var: Tensor
    std: Tensor
    mse: Tensor
    rmse: Tensor
    max: Tensor
    min: Tensor
    median: Tensor
    p95: Tensor
    p99: Tensor
    count: Tensor  # type: ignore[assignment]  # shadows tuple.count on purpose (the statistic's name)
    psnr: Tensor | None

    def as_dict(self) -> dict[str, float]:
        """Plain-Python dict of a single set's statistics, for reports and JSON.

        ``count`` is an ``int`` stored as a float-compatible number; ``psnr`` is omitted when it is ``None``.

        Raises:
            ValueError: the statistics are per item of a batch (use ``[s.as_dict() for s in unbind(stats)]``).
        """
        if self.ave.dim() != 0:
            raise ValueError(
                f"as_dict: expected statistics of one set (0-dim fields), found shape {tuple(self.ave.shape)}"
            )
        out: dict[str, float] = {}
        for name, value in zip(self._fields, self, strict=True):
            if value is None:
                continue
            out[name] = int(value.item()) if name == "count" else float(value.item())
        return out

    def as_tensors(self) -> dict[str, Tensor]:
        """The statistics as a dict of float64 tensors (``count`` too), for ``torchmetrics`` and ``log_dict``.

        ``psnr`` is omitted when it is ``None``.

        Example:
            >>> s = distance_statistics(torch.tensor([3.0, 4.0]))
            >>> s.as_tensors()["count"]
            tensor(2., dtype=torch.float64)
        """
        return {name: v.to(torch.float64) for name, v in zip(self._fields, self, strict=True) if v is not None}

    def unbind(self) -> list[DistanceStatistics]:
        """Split ``(B,)`` statistics into ``B`` single-set statistics."""
        if self.ave.dim() == 0:
            return [self]
        cols = [None if v is None else v.unbind(0) for v in self]
        return [DistanceStatistics._make(None if c is None else c[b] for c in cols) for b in range(self.ave.shape[0])]


def psnr_from_mse(mse: Tensor | float, peak: float | Tensor) -> Tensor:
    """MPEG-style geometry PSNR, ``10 log10(peak^2 / mse)`` dB; ``+inf`` where ``mse == 0``.

    Args:
        mse: mean squared errors, a tensor of any shape or a real number, each ``>= 0`` (``inf`` gives ``-inf`` dB).
        peak: the PSNR peak, a finite number ``> 0`` or a tensor of them that broadcasts against ``mse``.

    Returns:
        float64 PSNRs in dB, of ``mse``'s shape broadcast with ``peak``'s.

    Raises:
        TypeError: ``mse`` or ``peak`` is not a number or a real tensor.
        ValueError: an ``mse`` is negative or NaN (``-1`` gave ``+inf`` dB), or a peak is not finite and positive
            (``0`` gave ``-inf`` dB, NaN NaN).

    Example:
        >>> psnr_from_mse(torch.tensor(0.01, dtype=torch.float64), 1.0).item()
        20.0
        >>> psnr_from_mse(0.01, 1.0).item()  # a number is a one-element mse
        20.0
    """
    if not isinstance(mse, Tensor):
        value = as_real(mse, "mse")
        if value is None:
            raise TypeError(f"mse: expected a tensor or a real number, found {type(mse).__name__} {mse!r}")
        mse = torch.tensor(value, dtype=torch.float64)
    if mse.is_complex() or mse.dtype == torch.bool:
        raise TypeError(f"mse: expected a real tensor, found dtype {mse.dtype}")
    check_has_values(mse, "mse")
    bad = torch.isnan(mse) | (mse < 0)
    if bool(bad.any()):
        raise ValueError(
            f"mse: expected mean squared errors >= 0, found {float(mse.detach().reshape(-1)[bad.reshape(-1)][0])!r}"
        )
    return _psnr_db(mse, _check_peak(peak))


def _psnr_db(mse: Tensor, peak: float | Tensor) -> Tensor:
    """:func:`psnr_from_mse` of checked inputs (an empty set's NaN ``mse`` gives NaN)."""
    p = torch.as_tensor(peak, dtype=torch.float64, device=mse.device)
    mse = mse.to(torch.float64)
    val = 10.0 * torch.log10(p * p / mse.clamp_min(torch.finfo(torch.float64).tiny))
    # Where peak**2 or the quotient leaves float64's range (inf, 0 or NaN), or a subnormal mse was clamped, the same
    # PSNR as a difference of logarithms, which forms neither. Only there: the plain form's bits are the pinned ones.
    plain = torch.isfinite(val) & (mse >= torch.finfo(torch.float64).tiny)
    val = torch.where(plain, val, 20.0 * torch.log10(p) - 10.0 * torch.log10(mse))
    return torch.where(mse > 0, val, torch.full_like(val, math.inf))


_LOOP_MIN_MEAN = 8
"""Mean item size from which :func:`_sorted_within_items` sorts item by item with numpy (below it, two torch sorts
of all items; the crossover measured at 10k items of 9 values, one thread: 0.0082 s the torch sorts, 0.0092 s numpy
by item, 2026-12-07)."""


def _sorted_within_items(x: Tensor, lens: Tensor) -> Tensor:
    """``x`` (packed by ``lens``) with each item's values sorted ascending (NaN last).

    On the CPU each item is sorted by numpy (its vectorised sort): torch's stable sort of the whole packed tensor,
    then by item, took 20x longer (43.8 ms against 1.8 ms for 400k float64 values, one thread, 2026-12-07), and
    ``compute()`` of a metric and each statistics call is mostly that sort. Any two sorts of the same values give the
    same sequence but for the order of equal values, which differ only in the sign of a zero (and a NaN's payload);
    the interpolation in :func:`linear_quantiles` gives +0 for any signs of zeros, so the quantiles are the same bits.
    Elsewhere (CUDA: no host read of ``lens``) the two stable torch sorts.
    """
    nb = lens.numel()
    if x.device.type == "cpu" and lens.device.type == "cpu" and nb:
        lo, hi, total = int(lens.min()), int(lens.max()), int(lens.sum())
        if total == x.numel() and lo >= 0:  # else the torch path, as before
            import numpy as np

            a = x.numpy(force=True)
            if nb == 1:
                return torch.from_numpy(np.sort(a))
            if lo == hi:  # items of one size: one sort along rows
                return torch.from_numpy(np.sort(a.reshape(nb, lo), axis=1).reshape(-1))
            if a.size >= _LOOP_MIN_MEAN * nb:
                out = np.empty_like(a)
                start = 0
                for n in lens.tolist():
                    out[start : start + n] = np.sort(a[start : start + n])
                    start += n
                return torch.from_numpy(out)
            # many tiny items of several sizes: a sort call per item (~1 us each) loses to the two torch sorts below
            # (100k items of 2-3 values: 0.087 s by item, 0.024 s the two sorts; numpy's lexsort 0.035 s)
    b = batch_index(lens)
    # Sort by value, then stably by item: values sorted within each item.
    order = torch.argsort(x, stable=True)
    order = order[torch.argsort(b[order], stable=True)]
    return x[order]


def linear_quantiles(values: Tensor, q: Sequence[float] | Tensor, lengths: Tensor | None = None) -> Tensor:
    """Exact quantiles with linear interpolation (``numpy.percentile(..., method="linear")``), per item.

    Args:
        values: ``(N,)`` finite real values, or packed ``(sum N_b,)`` with ``lengths``.
        q: ``Q`` levels in ``[0, 1]`` (a sequence of numbers or a 1-D tensor).
        lengths: optional ``(B,)`` item sizes summing to ``N``.

    Returns:
        ``(Q,)`` (or ``(B, Q)`` with ``lengths``) float64 quantiles; NaN for empty items.

    Raises:
        ShapeError: ``values`` is not 1-D, ``q`` not a flat sequence, or ``lengths`` does not sum to ``N``.
        NonFiniteError: ``values`` holds NaN or Inf.
        ValueError: a level is outside ``[0, 1]`` or NaN (``-0.1`` read a value from the other end; NaN raised an
            ``IndexError``).

    Example:
        >>> linear_quantiles(torch.tensor([1.0, 2.0, 3.0, 4.0]), [0.5]).tolist()
        [2.5]
        >>> linear_quantiles(torch.tensor([1.0, 2.0]), [1.5])
        Traceback (most recent call last):
        ...
        ValueError: q: expected levels in [0, 1], found 1.5
    """
    check_shape(values, ("N",), "values")
    if values.is_complex() or values.dtype == torch.bool:
        raise TypeError(f"values: expected a float or integer tensor, found dtype {values.dtype}")
    check_finite(values, "values")
    if isinstance(q, Tensor):
        levels = q.detach().to("cpu", torch.float64)
        if levels.dim() > 1:
            raise ShapeError(f"q: expected a 1-D tensor of levels, found shape {tuple(levels.shape)}")
        found = levels.reshape(-1).tolist()
    elif isinstance(q, Sequence) and not isinstance(q, str):
        found = [check_real(level, f"q[{i}]") for i, level in enumerate(q)]
    else:
        raise TypeError(f"q: expected a sequence of levels in [0, 1] or a 1-D tensor, found {type(q).__name__} {q!r}")
    outside = [level for level in found if not 0.0 <= level <= 1.0]  # NaN too
    if outside:
        raise ValueError(f"q: expected levels in [0, 1], found {outside[0]!r}")
    if lengths is not None:
        check_lengths(lengths, values.shape[0], "lengths")
    return _linear_quantiles(values, q, lengths)


def _linear_quantiles(values: Tensor, q: Sequence[float] | Tensor, lengths: Tensor | None = None) -> Tensor:
    """:func:`linear_quantiles` of checked inputs (the distance statistics checked them once, at their door)."""
    x = values.detach().reshape(-1).to(torch.float64)
    qs = torch.as_tensor(q, dtype=torch.float64, device=x.device).reshape(-1)
    single = lengths is None
    lens = x.new_tensor([x.numel()], dtype=torch.long) if lengths is None else lengths.to(x.device, torch.long)
    xs = _sorted_within_items(x, lens)
    off = lengths_to_offsets(lens)[:-1]
    n = lens.to(torch.float64)
    pos = qs[None, :] * (n[:, None] - 1).clamp_min(0)
    lo, hi = torch.floor(pos), torch.ceil(pos)
    frac = pos - lo
    last = max(x.numel() - 1, 0)
    if x.numel() == 0:
        out = torch.full((lens.numel(), qs.numel()), float("nan"), dtype=torch.float64, device=x.device)
    else:
        lo_v = xs[(off[:, None] + lo.long()).clamp(max=last)]
        hi_v = xs[(off[:, None] + hi.long()).clamp(max=last)]
        out = lo_v + frac * (hi_v - lo_v)
        out = torch.where((lens > 0)[:, None], out, torch.full_like(out, float("nan")))
    return out[0] if single else out


def statistics_from_parts(
    moments: Moments,
    quantiles: Tensor,
    *,
    ddof: int = 0,
    peak: float | Tensor | None = None,
    values: Tensor | None = None,
    lengths: Tensor | None = None,
) -> DistanceStatistics:
    """Finish :class:`DistanceStatistics` from merged :class:`Moments` and quantiles ``(..., 3)``.

    Empty sets (``count == 0``) get NaN statistics (``count`` 0); ``var``/``std`` are NaN when ``count <= ddof``.
    ``values`` (the set's distances, packed with ``lengths`` for a batch), when kept, give ``rmse`` and ``std``
    where ``mse`` or ``var`` over- or underflowed (see :func:`_scaled_roots`).

    Args:
        moments: the merged :class:`~torchmeshmetric.stats.moments.Moments` (0-dim fields, or ``(B,)``).
        quantiles: ``(..., 3)`` median, p95 and p99 of each set.
        ddof: delta degrees of freedom of ``var``/``std``.
        peak: PSNR peak (a number or one per item), or ``None`` (no PSNR).
        values: the sets' distances (packed with ``lengths``), when kept.
        lengths: ``(B,)`` set sizes of packed ``values``.

    Returns:
        :class:`DistanceStatistics` of the fields' shape.

    Raises:
        TypeError, ValueError: ``ddof`` not an int >= 0, or ``peak`` not finite and positive.
        ShapeError: a ``peak`` tensor of another shape than the sets'.

    Example:
        >>> d = torch.tensor([1.0, 2.0, 3.0, 4.0], dtype=torch.float64)
        >>> s = statistics_from_parts(moments_of(d), linear_quantiles(d, QUANTILE_LEVELS), peak=10.0, values=d)
        >>> s.ave.item(), s.median.item(), round(s.psnr.item(), 4)
        (2.5, 2.5, 11.2494)
    """
    given: object = ddof
    if isinstance(given, float) and given.is_integer():
        given = int(given)  # ddof=1.0 worked before ddof was checked (numpy takes it too); 1.5 is refused
    ddof = check_int(given, "ddof", low=0)
    if peak is not None:
        peak = _check_peak(peak)
    n = moments.count.to(torch.float64)
    if isinstance(peak, Tensor) and peak.dim():
        if n.dim() == 0 and peak.numel() == 1:
            peak = peak.reshape(())  # one set, one peak
        elif tuple(peak.shape) != tuple(n.shape):  # (2,) for one set gave two PSNRs; (3,) for two, torch's error
            raise ShapeError(
                f"peak: expected a number or a tensor of shape {tuple(n.shape)} (one peak per item), found shape "
                f"{tuple(peak.shape)}"
            )
    nan = torch.full_like(n, float("nan"))
    has = n > 0
    ave = torch.where(has, moments.mean, nan)
    var = torch.where(n > ddof, moments.m2 / (n - ddof).clamp_min(1.0), nan)
    mse = torch.where(has, moments.sumsq / n.clamp_min(1.0), nan)
    rmse, std = mse.sqrt(), var.sqrt()
    # mse and var out of float64's normal range: overflowed (distances beyond ~1e154), or underflowed to a subnormal
    # or 0 though some distance is not 0 (below ~1e-154: rmse was 0 < ave, std 0 for three different values, the
    # PSNR inf; found by review). A constant set's var is 0 exactly and stays so.
    tiny = torch.finfo(torch.float64).tiny
    out_mse = torch.isinf(mse) | ((mse < tiny) & (moments.max > 0))
    out_var = torch.isinf(var) | ((var < tiny) & (moments.max > moments.min))
    if bool((out_mse | out_var).any()):  # only there: the usual case's bits are the plain roots'
        mse, var, rmse, std = _scaled_roots(moments, mse, var, out_mse, out_var, ddof, values, lengths)
    psnr = None
    if peak is not None:
        p = torch.as_tensor(peak, dtype=torch.float64, device=mse.device)
        # An mse out of range has no PSNR of its own: 10 log10(peak^2 / mse) = 20 log10(peak / rmse).
        psnr = torch.where(out_mse, 20.0 * (torch.log10(p) - torch.log10(rmse)), _psnr_db(mse, p))
        psnr = torch.where(has, psnr, nan)
    return DistanceStatistics(
        ave=ave,
        var=var,
        std=std,
        mse=mse,
        rmse=rmse,
        max=torch.where(has, moments.max, nan),
        min=torch.where(has, moments.min, nan),
        median=quantiles[..., 0],
        p95=quantiles[..., 1],
        p99=quantiles[..., 2],
        count=n.round().long(),
        psnr=psnr,
    )


def _scaled_roots(
    moments: Moments,
    mse: Tensor,
    var: Tensor,
    out_mse: Tensor,
    out_var: Tensor,
    ddof: int,
    values: Tensor | None,
    lengths: Tensor | None,
) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    r"""``(mse, var, rmse, std)`` where ``mse`` (``out_mse``) or ``var`` (``out_var``) left float64's normal range.

    ``mse`` overflows for distances beyond ~1e154 and underflows below ~1e-154 (subnormal: digits lost; 0), and
    ``var`` likewise for a spread beyond or below those: their true values may be past float64, but ``rmse`` and
    ``std`` (of the order of the distances) never are. With the values at hand (exact quantiles keep them), all four
    are recomputed from the values scaled by an exact power of two per item (``max|d|`` into ``[0.5, 1)``); ``mse``
    and ``var`` are then their true values rounded (``inf`` or 0 only where those are past float64). Without them
    (the quantile sketch): an overflowed ``rmse`` is :math:`\sqrt{\mathrm{Var}_0 + \mathrm{Ave}^2}` by ``hypot``
    from the moments, finite while ``m2`` is (a near-constant set), and ``std`` stays ``inf``; an underflowed
    ``rmse`` / ``std`` is NaN, unknown (the moments' squares lost it), never a 0 below ``ave``.
    """
    rmse, std = mse.sqrt(), var.sqrt()
    n = moments.count.to(torch.float64)
    if values is None:
        nan = torch.full_like(rmse, float("nan"))
        identity = torch.hypot(moments.mean, (moments.m2 / n.clamp_min(1.0)).sqrt())
        rmse = torch.where(torch.isinf(mse), identity, torch.where(out_mse, nan, rmse))
        std = torch.where(out_var & ~torch.isinf(var), nan, std)
        return mse, var, rmse, std
    x = values.detach().reshape(-1).to(torch.float64)
    shape = n.shape
    n, mean = n.reshape(-1), moments.mean.reshape(-1)
    scale = power_of_two_scale_down(torch.maximum(moments.min.abs(), moments.max.abs()).reshape(-1))
    b = x.new_zeros(x.shape, dtype=torch.long) if lengths is None else batch_index(lengths.to(x.device, torch.long))
    xs = x * scale[b]
    sq = x.new_zeros(n.shape).index_add_(0, b, xs * xs)
    dev = x.new_zeros(n.shape).index_add_(0, b, (xs - (mean * scale)[b]) ** 2)
    scaled_mse, scaled_var = sq / n.clamp_min(1.0), dev / (n - ddof).clamp_min(1.0)
    scale = scale.reshape(shape)
    # divided back twice: the square of the scale of distances near 1e-300 overflows
    true_mse = scaled_mse.reshape(shape) / scale / scale
    true_var = scaled_var.reshape(shape) / scale / scale
    scaled_rmse = scaled_mse.sqrt().reshape(shape) / scale
    scaled_std = scaled_var.sqrt().reshape(shape) / scale
    return (
        torch.where(out_mse, true_mse, mse),
        torch.where(out_var, true_var, var),
        torch.where(out_mse, scaled_rmse, rmse),
        torch.where(out_var, scaled_std, std),
    )


def _check_peak(peak: float | Tensor) -> float | Tensor:
    """Require a finite, positive PSNR peak (a number or a tensor of them): 0 gave -inf dB, NaN NaN, -1 that of +1."""
    if isinstance(peak, Tensor):
        _check_distances(peak, "peak")
        bad = peak.detach().to(torch.float64) <= 0
        if bool(bad.any()):
            raise ValueError(f"peak: expected positive values, found {float(peak.reshape(-1)[bad.reshape(-1)][0])!r}")
        return peak
    value = check_real(peak, "peak")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"peak: expected a finite number > 0, found {value!r}")
    return value


def derived_peak(peak: float, what: str) -> float:
    """A PSNR peak the library derived (a reference's bounding-box diagonal), checked under ``what`` it came from.

    The user gave no ``peak``: an error about one would name an argument they never passed (found by review).

    Raises:
        ValueError: the diagonal is 0 (every referenced vertex at one point) or not finite (coordinates whose
            extent overflows float64); the message names ``what`` and asks for an explicit peak.

    Example:
        >>> derived_peak(2.0, "original_k")
        2.0
    """
    if not (math.isfinite(peak) and peak > 0):
        raise ValueError(
            f"{what}: its bounding-box diagonal, the default PSNR peak, is {peak!r}, and the PSNR needs a finite "
            "positive peak (a reference whose referenced vertices are all one point has none); pass peak= explicitly"
        )
    return peak


def distance_statistics(
    dists: Tensor | Sequence[Tensor],
    *,
    lengths: Tensor | None = None,
    ddof: int = 0,
    peak: float | Tensor | None = None,
    exact_quantiles: bool = True,
    relative_accuracy: float = 1e-3,
) -> DistanceStatistics:
    """All statistics of a distance set, or of every item of a ragged batch.

    Definitions (``d`` distances, not squared; ``n`` their count):
    ``ave = mean(d)``, ``var = sum((d - ave)^2) / (n - ddof)``, ``std = sqrt(var)``, ``mse = mean(d^2)``,
    ``rmse = sqrt(mse)``, ``max``/``min`` (``max`` is the one-sided Hausdorff distance), ``median``/``p95``/``p99``
    (linear interpolation, as ``numpy.percentile``), ``psnr = 10 log10(peak^2 / mse)`` dB. With ``ddof=0``
    (default, population variance) ``mse = var + ave^2``. Computed in float64, two-pass (no cancellation).

    Args:
        dists: ``(N,)`` distances; a packed ``(sum N_b,)`` tensor with ``lengths``; or a list of ``(N_b,)`` tensors.
        lengths: ``(B,)`` item sizes of a packed batch.
        ddof: delta degrees of freedom of the variance (0: population, the default; 1: sample).
        peak: PSNR peak (MPEG convention: e.g. the reference's bounding-box diagonal). ``None``: ``psnr`` is
            ``None`` (never NaN by omission). A ``(B,)`` tensor gives one peak per item.
        exact_quantiles: exact quantiles (sorts the values) or the sketch estimate with relative error
            ``relative_accuracy`` (see :class:`~torchmeshmetric.stats.sketch.QuantileSketch`), at any scale: the
            sketch's window follows each set (:meth:`~torchmeshmetric.stats.sketch.QuantileSketch.quantiles_of`;
            values below ~1e-12 of the set's mean have an absolute error below that instead).
        relative_accuracy: the sketch's relative-error bound when ``exact_quantiles=False``.

    Returns:
        :class:`DistanceStatistics`: float64 0-dim fields for a single set, ``(B,)`` for a batch (list or
        ``lengths``). ``psnr`` is ``+inf`` where ``mse == 0``. Empty items of a batch have ``count = 0`` and NaN
        statistics; ``var``/``std`` are NaN when ``count <= ddof`` (as ``numpy.var``).

    Raises:
        EmptyInputError: a single (non-batched) set is empty.
        NonFiniteError: a distance is NaN or Inf.
        ShapeError: ``dists`` is not 1-D or ``lengths`` does not match.

    Example:
        >>> import torch
        >>> s = distance_statistics(torch.tensor([1.0, 2.0, 3.0, 4.0]), peak=10.0)
        >>> s.ave.item(), s.var.item(), s.mse.item(), s.median.item(), round(s.psnr.item(), 4)
        (2.5, 1.25, 7.5, 2.5, 11.2494)
    """
    exact_quantiles = check_flag(exact_quantiles, "exact_quantiles")
    if isinstance(dists, Tensor):
        d = dists
        check_shape(d, ("N",), "dists")
        if lengths is not None:
            check_lengths(lengths.to(d.device), d.shape[0], "lengths")
    else:
        if not isinstance(dists, Sequence):  # a numpy array was taken as a list of sets (its values)
            check_tensor(dists, "dists", "an (N,) torch.Tensor or a list of them")
        if lengths is not None:
            raise TypeError("lengths: only valid with a packed dists tensor, found a list of tensors")
        items = list(dists)
        if not items:
            raise EmptyInputError("dists: expected at least one distance set, found an empty list")
        for i, t in enumerate(items):
            check_shape(t, ("N",), f"dists[{i}]")
        lengths = torch.tensor([t.shape[0] for t in items], device=items[0].device)
        d = torch.cat([t.to(torch.float64) for t in items])
    sketch = None if exact_quantiles else QuantileSketch(relative_accuracy)
    if lengths is None:
        moments, values = distance_statistics_update(d, None)
        if sketch is not None:
            _check_sketch_input(d, "dists")
        if d.numel() == 0:
            raise EmptyInputError("dists: expected at least one distance, found an empty tensor")
        if sketch is None:
            return distance_statistics_compute(moments, values, ddof=ddof, peak=peak)
        # All values at hand: the sketch's window follows them (QuantileSketch.quantiles_of), not the fixed one.
        q = torch.tensor(QUANTILE_LEVELS, dtype=torch.float64, device=d.device)
        return statistics_from_parts(moments, sketch.quantiles_of(values, q), ddof=ddof, peak=peak, values=values)
    _check_distances(d, "dists")
    if sketch is not None:
        _check_sketch_input(d, "dists")
    mom = moments_of(d, lengths)
    if sketch is None:
        qv = _linear_quantiles(d, QUANTILE_LEVELS, lengths)
    else:
        q = torch.tensor(QUANTILE_LEVELS, dtype=torch.float64, device=d.device)
        b = batch_index(lengths.to(d.device, torch.long))
        rows = [sketch.quantiles_of(d[b == i], q) for i in range(int(lengths.numel()))]
        qv = torch.stack(rows) if rows else d.new_zeros((0, 3), dtype=torch.float64)
    return statistics_from_parts(mom, qv, ddof=ddof, peak=peak, values=d, lengths=lengths)


def _check_distances(dists: Tensor, name: str) -> None:
    """Require real (float or integer) and finite distances (computed in float64: integers beyond 2**53 round)."""
    if dists.is_complex() or dists.dtype == torch.bool:  # int16 was refused as "not a real tensor", int32 taken
        raise TypeError(f"{name}: expected a float or integer tensor, found dtype {dists.dtype}")
    check_finite(dists, name)


def _check_sketch_input(dists: Tensor, name: str) -> None:
    """Require distances >= 0 for the quantile sketch: its log buckets put a negative value in the wrong one."""
    if dists.numel() and float(dists.min()) < 0:
        raise ValueError(f"{name}: the quantile sketch takes distances >= 0, found {float(dists.min())!r}")


def distance_statistics_update(
    dists: Tensor, sketch: QuantileSketch | None = None, name: str = "dists"
) -> tuple[Moments, Tensor]:
    """Check one ``(N,)`` distance set and return its sufficient statistics (``N`` may be 0).

    The ``_update`` half of :func:`distance_statistics` (torchmetrics' functional shape): every accumulator of
    distances (:class:`~torchmeshmetric.stats.DistanceAccumulator`, the metrics of :mod:`torchmeshmetric.metrics`,
    :class:`~torchmeshmetric.evaluation.TemporalConsistency`) passes each batch through it and keeps what it returns.

    Args:
        dists: ``(N,)`` distances (float or int).
        sketch: ``None`` for exact quantiles, else the sketch whose counts estimate them.
        name: the argument's name in error messages.

    Returns:
        ``(moments, quantile_data)``: the set's 0-dim float64 :class:`~torchmeshmetric.stats.moments.Moments`, and
        what its quantiles are computed from: the ``(N,)`` float64 distances (``sketch=None``) or the sketch's
        ``(num_bins,)`` counts. Both merge across batches: moments by :func:`~torchmeshmetric.stats.merge_moments`,
        distances by concatenation, counts by addition.

    Raises:
        ShapeError: ``dists`` is not 1-D.
        TypeError: ``dists`` is not real.
        NonFiniteError: a distance is NaN or Inf.
        ValueError: a negative distance with a ``sketch`` (its quantiles would be wrong; exact ones take any sign).
    """
    check_shape(dists, ("N",), name)
    _check_distances(dists, name)
    d = dists.detach().to(torch.float64)
    if sketch is not None:
        _check_sketch_input(d, name)
    return moments_of(d), d if sketch is None else sketch.counts(d)


def distance_statistics_compute(
    moments: Moments,
    quantile_data: Tensor,
    *,
    sketch: QuantileSketch | None = None,
    ddof: int = 0,
    peak: float | Tensor | None = None,
    values: Tensor | None = None,
) -> DistanceStatistics:
    """Finish the statistics of one set from merged moments and its quantile data (the ``_compute`` half).

    Args:
        moments: 0-dim :class:`~torchmeshmetric.stats.moments.Moments` of the whole set (merged).
        quantile_data: the set's float64 distances (``sketch=None``) or its ``(num_bins,)`` sketch counts, as
            :func:`distance_statistics_update` returns them (concatenated or added over batches).
        sketch: the sketch that made the counts, ``None`` for exact quantiles.
        ddof: delta degrees of freedom of ``var``/``std``.
        peak: PSNR peak, or ``None`` (no PSNR).
        values: the set's distances where a sketch's caller still has them (exact quantiles: ``quantile_data``);
            read only where ``mse`` or ``var`` overflowed, to give a finite ``rmse``/``std``.

    Returns:
        0-dim :class:`DistanceStatistics`.

    Example:
        >>> import torch
        >>> s = distance_statistics_compute(*distance_statistics_update(torch.tensor([1.0, 2.0, 3.0, 4.0])))
        >>> s.ave.item(), s.var.item(), s.median.item()
        (2.5, 1.25, 2.5)
    """
    if sketch is None:
        quantiles = _linear_quantiles(quantile_data, QUANTILE_LEVELS)
    else:
        q = torch.tensor(QUANTILE_LEVELS, dtype=torch.float64, device=quantile_data.device)
        quantiles = sketch.quantile(quantile_data, q, moments.min, moments.max)
    if sketch is None:
        values = quantile_data
    return statistics_from_parts(moments, quantiles, ddof=ddof, peak=peak, values=values)


def mean_psnr(values: Sequence[float], what: str = "values") -> tuple[float, int]:
    """The mean of PSNR values (frames, frame pairs, sequences) and the number of infinite ones left out.

    The library's one rule for an infinite PSNR (a frame measured without error, ``mse == 0``) in a mean: the mean
    is taken over the finite values and the infinite ones are counted beside it; it is ``inf`` only when every value
    is. (A mean in dB with one ``inf`` would be ``inf`` and hide every other frame; mmetric, which has no clipping
    rule here, prints that.) The MPEG sequence averages (``<key>_inf_frames``), Tables III/IV's mean PSNR over
    frame pairs, a campaign's ``overall`` PSNR and ``compare``'s verdict threshold follow it; see
    ``docs/statistics.md``. Only ``+inf`` is left out: a NaN PSNR (a bug upstream, such as the PSNR of an empty set)
    or ``-inf`` (impossible for a finite peak) is refused, never dropped in silence.

    Args:
        values: the PSNRs, in dB.
        what: where the values come from, named by the error (``"the pairs' psnr"``).

    Returns:
        ``(mean, infinite)``: the mean of the finite values (``inf`` when every value is infinite) and the number of
        infinite values left out.

    Raises:
        ValueError: no value (it returned ``(nan, 0)`` though a NaN is refused, never dropped in silence; found by
            review), or a value is NaN or ``-inf``; the message names ``what`` and the value's position.

    Example:
        >>> mean_psnr([40.0, 50.0, float("inf")])
        (45.0, 1)
        >>> mean_psnr([float("inf")])
        (inf, 1)
    """
    if len(values) == 0:  # every caller's list holds a value; a direct call's empty one is a mistake to report
        raise ValueError(f"{what}: expected at least one PSNR, found none (a mean of nothing is no figure)")
    for i, v in enumerate(values):
        if math.isnan(v) or v == -math.inf:
            why = (
                "a NaN PSNR is a bug upstream (the PSNR of an empty set, or a NaN distance)"
                if math.isnan(v)
                else "a PSNR of -inf is impossible for a finite peak"
            )
            raise ValueError(f"{what}: PSNR {v} at position {i} of {len(values)} cannot enter a mean of PSNRs: {why}")
    finite = [v for v in values if math.isfinite(v)]
    infinite = len(values) - len(finite)
    if finite:
        return sum(finite) / len(finite), infinite
    return math.inf, infinite  # every value infinite (there is at least one)
