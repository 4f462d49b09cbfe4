"""``torchmetrics`` state handling shared by the distance metrics: exact, mergeable, DDP-synchronised statistics.

States (per direction ``fwd`` / ``rev``, prefixed by the metric's ``_state_prefix`` so that two different metrics
never share states in a ``MetricCollection`` compute group):

- ``count``, ``mean``, ``m2``: partial moments as rows, ``dist_reduce_fx="cat"``. Every ``update`` merges its
  batch into one row (Chan et al. 1979); DDP sync gathers one row per process and ``compute`` merges the rows
  with the same formula. This is exact: no state is averaged, and no ``E[d^2] - E[d]^2`` appears.
- ``sumsq``: sum of ``d^2`` (``"sum"``); ``min`` / ``max`` (``"min"`` / ``"max"``).
- quantiles: the values themselves (a list state, ``"cat"``) when ``exact_quantiles=True``, else the counts of a
  :class:`~torchmeshmetric.stats.sketch.QuantileSketch` (``"sum"``).
- ``peak``: the largest reference bounding-box diagonal seen (``"max"``), the default PSNR peak.

All float states are float64 (``Metric.half()``/``.float()`` leave them alone unless ``set_dtype`` is used).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torch import Tensor
from torchmetrics import Metric, MetricCollection
from torchmetrics.utilities.data import dim_zero_cat

from torchmeshmetric._checks import EmptyInputError, NonFiniteError, check_shape
from torchmeshmetric.metrics.directed_distances import DirectedDistances
from torchmeshmetric.metrics.selected_statistic import SelectedStatistic
from torchmeshmetric.stats.moments import Moments, merge_mean_m2, moments_of
from torchmeshmetric.stats.sketch import QuantileSketch
from torchmeshmetric.stats.statistics import (
    QUANTILE_LEVELS,
    DistanceStatistics,
    linear_quantiles,
    psnr_from_mse,
    statistics_from_parts,
)

__all__ = ["DistanceStatisticsBase", "DistanceStatisticsMetric"]

_DIRECTIONS = ("fwd", "rev")
_SYMMETRIC = ("symmetric_ave", "hausdorff", "symmetric_mse", "symmetric_rmse", "symmetric_psnr")


class DistanceStatisticsBase(Metric):
    """Base class: accumulates distances of one or two directions and computes :class:`DistanceStatistics`.

    Args:
        two_sided: accumulate and report the reverse direction and symmetric combinations too.
        peak: fixed PSNR peak; ``None`` uses the largest peak passed to updates (reference bbox diagonals).
        ddof: delta degrees of freedom of ``var``/``std`` (0: population, the default).
        exact_quantiles: keep all values for exact quantiles (default), or a fixed-size sketch whose quantiles are
            within relative error ``relative_accuracy`` (constant memory, cheap DDP sync).
        relative_accuracy: the sketch's bound.
        kwargs: ``torchmetrics.Metric`` options (``dist_sync_on_step``, ``process_group``, ...).
    """

    is_differentiable = False
    higher_is_better = False
    full_state_update = False
    plot_lower_bound = 0.0
    _state_prefix = "dist"
    # Whether every update brings a PSNR peak (the reference's bounding-box diagonal), so that psnr is always known.
    _peak_from_updates = True

    def __init__(
        self,
        *,
        two_sided: bool = False,
        peak: float | None = None,
        ddof: int = 0,
        exact_quantiles: bool = True,
        relative_accuracy: float = 1e-3,
        **kwargs: Any,
    ) -> None:
        super().__init__(**kwargs)
        if not isinstance(ddof, int) or ddof < 0:
            raise ValueError(f"ddof: expected a non-negative int, found {ddof!r}")
        if peak is not None and not (float(peak) >= 0):
            raise ValueError(f"peak: expected None or a non-negative number, found {peak!r}")
        self.two_sided = bool(two_sided)
        self.fixed_peak = None if peak is None else float(peak)
        self.ddof = ddof
        self.exact_quantiles = bool(exact_quantiles)
        self.sketch = QuantileSketch(relative_accuracy)
        f64 = torch.float64
        for d in _DIRECTIONS if self.two_sided else _DIRECTIONS[:1]:
            for field in ("count", "mean", "m2"):
                self.add_state(self._name(d, field), default=torch.zeros(0, dtype=f64), dist_reduce_fx="cat")
            self.add_state(self._name(d, "sumsq"), default=torch.zeros((), dtype=f64), dist_reduce_fx="sum")
            self.add_state(self._name(d, "min"), default=torch.tensor(float("inf"), dtype=f64), dist_reduce_fx="min")
            self.add_state(self._name(d, "max"), default=torch.tensor(float("-inf"), dtype=f64), dist_reduce_fx="max")
            if self.exact_quantiles:
                self.add_state(self._name(d, "values"), default=[], dist_reduce_fx="cat")
            else:
                self.add_state(
                    self._name(d, "sketch"), default=torch.zeros(self.sketch.num_bins, dtype=f64), dist_reduce_fx="sum"
                )
        self.add_state(self._name("all", "peak"), default=torch.tensor(float("-inf"), dtype=f64), dist_reduce_fx="max")

    def _name(self, direction: str, field: str) -> str:
        return f"{self._state_prefix}_{direction}_{field}"

    def _get(self, direction: str, field: str) -> Any:
        return getattr(self, self._name(direction, field))

    def _set(self, direction: str, field: str, value: Any) -> None:
        setattr(self, self._name(direction, field), value)

    def _accumulate(self, direction: str, dists: Tensor) -> None:
        """Add a ``(N,)`` tensor of distances to one direction (``N = 0`` is a no-op)."""
        d = dists.detach().reshape(-1).to(torch.float64)
        if d.numel() == 0:
            return
        if not bool(torch.isfinite(d).all()):
            raise NonFiniteError(f"dists: expected finite values, found {int((~torch.isfinite(d)).sum())} NaN/Inf")
        new = moments_of(d)
        dev = self._get(direction, "count").device
        parts: list[Tensor] = [
            torch.cat([self._get(direction, f), getattr(new, f).reshape(1).to(dev)]) for f in ("count", "mean", "m2")
        ]
        n, mean, m2 = merge_mean_m2(parts[0], parts[1], parts[2])
        self._set(direction, "count", n.reshape(1))
        self._set(direction, "mean", mean.reshape(1))
        self._set(direction, "m2", m2.reshape(1))
        self._set(direction, "sumsq", self._get(direction, "sumsq") + new.sumsq.to(dev))
        self._set(direction, "min", torch.minimum(self._get(direction, "min"), new.min.to(dev)))
        self._set(direction, "max", torch.maximum(self._get(direction, "max"), new.max.to(dev)))
        if self.exact_quantiles:
            self._get(direction, "values").append(d.to(dev))
        else:
            self._set(direction, "sketch", self._get(direction, "sketch") + self.sketch.counts(d).to(dev))

    def _accumulate_directed(self, r: DirectedDistances) -> None:
        self._accumulate("fwd", r.forward)
        if self.two_sided and r.reverse is not None:
            self._accumulate("rev", r.reverse)
        if r.peak.numel():
            self._update_peak(r.peak.max())

    def _update_peak(self, peak: Tensor | float) -> None:
        p = torch.as_tensor(peak, dtype=torch.float64).to(self._get("all", "peak").device)
        self._set("all", "peak", torch.maximum(self._get("all", "peak"), p))

    def _peak(self) -> float | None:
        if self.fixed_peak is not None:
            return self.fixed_peak
        p = float(self._get("all", "peak"))
        return p if p >= 0 else None

    def _direction_statistics(self, direction: str) -> DistanceStatistics:
        count = self._get(direction, "count")
        n = float(count.sum()) if count.numel() else 0.0
        if n == 0:
            which = "simplified → reference" if direction == "fwd" else "reference → simplified"
            raise EmptyInputError(
                f"{type(self).__name__}.compute: no {which} distances were accumulated; call update() with "
                "non-empty inputs first"
            )
        # Rows of (count, mean, m2) come from updates, forward() calls and processes: merge them all.
        n_all, mean, m2 = merge_mean_m2(count, self._get(direction, "mean"), self._get(direction, "m2"))
        mom = Moments(
            n_all,
            mean,
            m2,
            self._get(direction, "sumsq").reshape(()),
            self._get(direction, "min").reshape(()),
            self._get(direction, "max").reshape(()),
        )
        q = torch.tensor(QUANTILE_LEVELS, dtype=torch.float64, device=mom.count.device)
        if self.exact_quantiles:
            qv = linear_quantiles(dim_zero_cat(self._get(direction, "values")), q)
        else:
            qv = self.sketch.quantile(self._get(direction, "sketch"), q, mom.min, mom.max)
        return statistics_from_parts(mom, qv, ddof=self.ddof, peak=self._peak())

    def compute_statistics(self) -> dict[str, DistanceStatistics]:
        """The accumulated :class:`DistanceStatistics` per direction: ``{"forward": ..., "reverse": ...}``."""
        out = {"forward": self._direction_statistics("fwd")}
        if self.two_sided:
            out["reverse"] = self._direction_statistics("rev")
        return out

    def statistic_names(self) -> tuple[str, ...]:
        """The keys of :meth:`compute`, in order, for this metric's configuration.

        ``psnr`` keys are listed when a peak is always known: a constructor ``peak``, or a metric whose updates
        measure a reference (every metric but :class:`DistanceStatisticsMetric`).
        """
        psnr = self.fixed_peak is not None or self._peak_from_updates
        fields = tuple(f for f in DistanceStatistics._fields if psnr or f != "psnr")
        if not self.two_sided:
            return fields
        return fields + tuple("reverse_" + f for f in fields) + tuple(s for s in _SYMMETRIC if psnr or "psnr" not in s)

    def statistic(self, key: str) -> SelectedStatistic:
        """A scalar metric reporting ``self.compute()[key]``, for ``self.log(name, metric)`` in Lightning.

        The view shares this metric's accumulation: keep calling ``update`` on this metric; logging the view makes
        Lightning compute it at the end of the epoch and reset this metric. See
        :class:`~torchmeshmetric.metrics.SelectedStatistic`.

        Raises:
            ValueError: ``key`` is not one of :meth:`statistic_names`.
        """
        return SelectedStatistic(self, key)

    def statistics(
        self, keys: Sequence[str] | None = None, *, prefix: str | None = None, postfix: str | None = None
    ) -> MetricCollection:
        """A ``MetricCollection`` of :meth:`statistic` views, for ``self.log_dict(collection)`` in Lightning.

        Args:
            keys: the statistics to report (default: all of :meth:`statistic_names`).
            prefix: prepended to every key in the collection's names (e.g. ``"val/surface_"``).
            postfix: appended to every key.

        Returns:
            A collection whose ``compute()`` is the selected part of ``self.compute()`` (keys with prefix/postfix)
            and whose members are scalar metrics sharing this metric's single accumulation.

        Raises:
            ValueError: a key is not one of :meth:`statistic_names`, or ``keys`` is empty or repeats a key.

        Example:
            >>> import torch
            >>> metric = DistanceStatisticsMetric()
            >>> logged = metric.statistics(["ave", "max"], prefix="val/")
            >>> metric.update(torch.tensor([1.0, 2.0, 6.0]))
            >>> {k: v.item() for k, v in logged.compute().items()}
            {'val/ave': 3.0, 'val/max': 6.0}
        """
        keys = self.statistic_names() if keys is None else tuple(keys)
        if len(keys) == 0 or len(set(keys)) != len(keys):
            raise ValueError(f"keys: expected distinct statistic names, found {keys!r}")
        return MetricCollection(
            {k: self.statistic(k) for k in keys}, prefix=prefix, postfix=postfix, compute_groups=False
        )

    def compute(self) -> dict[str, Tensor]:
        """Dict of 0-dim float64 tensors (``count`` included, as float64, so that every value logs as a float).

        Raises:
            EmptyInputError: nothing was accumulated in a reported direction.
        """
        stats = self.compute_statistics()
        out: dict[str, Tensor] = {}
        for key, prefix in (("forward", ""), ("reverse", "reverse_")):
            if key not in stats:
                continue
            for name, value in zip(DistanceStatistics._fields, stats[key], strict=True):
                if value is not None:
                    out[prefix + name] = value.to(torch.float64)
        if self.two_sided:
            f, r = stats["forward"], stats["reverse"]
            out["symmetric_ave"] = 0.5 * (f.ave + r.ave)
            out["hausdorff"] = torch.maximum(f.max, r.max)
            out["symmetric_mse"] = torch.maximum(f.mse, r.mse)
            out["symmetric_rmse"] = out["symmetric_mse"].sqrt()
            peak = self._peak()
            if peak is not None:
                out["symmetric_psnr"] = psnr_from_mse(out["symmetric_mse"], peak)
        return out


class DistanceStatisticsMetric(DistanceStatisticsBase):
    """Statistics of precomputed distances, accumulated over batches and processes (no geometry).

    ``update(dists, reverse_dists=None, *, peak=None)`` takes ``(N,)`` distance tensors (e.g. from
    :func:`~torchmeshmetric.point_mesh_distance`); ``compute()`` returns the same dict as
    :class:`~torchmeshmetric.metrics.MeshSurfaceDistance`. PSNR keys appear only when a peak is known (the
    constructor's ``peak`` or a ``peak`` passed to ``update``).

    Example:
        >>> import torch
        >>> m = DistanceStatisticsMetric(peak=10.0)
        >>> m.update(torch.tensor([1.0, 2.0]))
        >>> m.update(torch.tensor([3.0, 4.0]))
        >>> out = m.compute()
        >>> out["ave"].item(), out["var"].item(), out["mse"].item(), out["count"].item()
        (2.5, 1.25, 7.5, 4.0)
    """

    _peak_from_updates = False

    def update(self, dists: Tensor, reverse_dists: Tensor | None = None, *, peak: float | Tensor | None = None) -> None:
        """Accumulate ``(N,)`` forward distances (and ``(R,)`` reverse ones when ``two_sided``)."""
        check_shape(dists, ("N",), "dists")
        self._accumulate("fwd", dists)
        if self.two_sided:
            if reverse_dists is None:
                raise TypeError("reverse_dists: expected a (R,) tensor because two_sided=True, found None")
            check_shape(reverse_dists, ("R",), "reverse_dists")
            self._accumulate("rev", reverse_dists)
        elif reverse_dists is not None:
            raise TypeError("reverse_dists: only valid with two_sided=True")
        if peak is not None:
            self._update_peak(torch.as_tensor(peak, dtype=torch.float64).max())
