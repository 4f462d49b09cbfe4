"""``torchmetrics`` base of the distance metrics: statistics of one or two directions, exact and DDP-synchronised.

Each direction (forward: simplified → reference; reverse: reference → simplified) is one distance set held in the
states a :class:`~torchmeshmetric.metrics.distance_states.DistanceStates` names (moments rows, values or sketch
counts; see there for their DDP semantics). Each metric class declares its own state names, so that two different
metrics never share states in a ``MetricCollection`` compute group (torchmetrics groups metrics whose states have the
same names and values); the settings digest of :class:`~torchmeshmetric.metrics._settings.SettingsMetric` keeps two
configurations of one class apart (``surface_samples``, ``two_sided``, the quantile mode), and ``merge_state`` refuses
to pool them. ``reference_peak`` is the largest reference bounding-box diagonal seen (``"max"``), the
default PSNR peak.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable, Sequence
from typing import Any

import torch
from torch import Tensor
from torchmetrics import Metric, MetricCollection

from torchmeshmetric._checks import check_flag, check_int, check_shape
from torchmeshmetric.metrics._plot import StatisticsPlot
from torchmeshmetric.metrics.directed_distances import DirectedDistances
from torchmeshmetric.metrics.distance_states import DistanceStates, DistanceStatesMetric
from torchmeshmetric.metrics.selected_statistic import SelectedStatistic
from torchmeshmetric.stats.sketch import QuantileSketch
from torchmeshmetric.stats.statistics import DistanceStatistics, derived_peak, distance_statistics_update

__all__ = ["DistanceStatisticsBase", "DistanceStatisticsMetric", "MeasuredDistanceBase"]

_SYMMETRIC = ("symmetric_ave", "hausdorff", "symmetric_mse", "symmetric_rmse", "symmetric_psnr")


class DistanceStatisticsBase(StatisticsPlot, DistanceStatesMetric):
    """Base class: accumulates distances of one or two directions and computes :class:`DistanceStatistics`.

    A subclass declares the names of its states as class constants ``_forward_states`` and ``_reverse_states``
    (:class:`~torchmeshmetric.metrics.distance_states.DistanceStates`), names no other metric class uses.

    ``plot()`` draws ``compute()``'s statistics as bars, or a list of results as curves (see
    :class:`~torchmeshmetric.metrics._plot.StatisticsPlot`).

    Args:
        two_sided: accumulate and report the reverse direction and symmetric combinations too.
        peak: fixed PSNR peak (finite, > 0); ``None`` uses the largest peak passed to updates (reference bbox
            diagonals).
        ddof: delta degrees of freedom of ``var``/``std`` (0: population, the default).
        exact_quantiles: keep all values for exact quantiles (default), or a fixed-size sketch whose quantiles are
            within relative error ``relative_accuracy`` (constant memory, cheap DDP sync) where they lie in its
            fixed window ``[1e-12, 1e12]`` (a quantile outside it warns,
            :class:`~torchmeshmetric.stats.sketch.SketchRangeWarning`).
        relative_accuracy: the sketch's bound.
        kwargs: ``torchmetrics.Metric`` options (``dist_sync_on_step``, ``process_group``, ...).

    Example:
        >>> from torchmeshmetric import DistanceStatisticsMetric, MeshSurfaceDistance
        >>> issubclass(DistanceStatisticsMetric, DistanceStatisticsBase)  # what the metrics share
        True
        >>> issubclass(MeshSurfaceDistance, DistanceStatisticsBase)
        True
    """

    is_differentiable = False
    higher_is_better = False
    full_state_update = False
    plot_lower_bound = 0.0
    # Declared per class (see the module docstring); subclasses declare their own names.
    _forward_states = DistanceStates("forward_moments", "forward_values", "forward_sketch")
    _reverse_states = DistanceStates("reverse_moments", "reverse_values", "reverse_sketch")
    reference_peak: Tensor
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
        # as update(peak=) checks it: peak=0 gave a PSNR of -inf, and "no" for a flag was taken as True
        self.fixed_peak = None if peak is None else float(_checked_peak(peak))
        self.two_sided = check_flag(two_sided, "two_sided")
        self.ddof = check_int(ddof, "ddof", 0)
        self.exact_quantiles = check_flag(exact_quantiles, "exact_quantiles")
        self.sketch = QuantileSketch(relative_accuracy)
        self._forward_states.add_to(self, self._sketch)
        if self.two_sided:
            self._reverse_states.add_to(self, self._sketch)
        self.add_state("reference_peak", default=torch.tensor(float("-inf"), dtype=torch.float64), dist_reduce_fx="max")

    def _setting_items(self) -> dict[str, object]:
        """The directions and the quantile mode.

        Sketches of two accuracies were added bin by bin: a raw size mismatch, or a wrong figure had they the same
        size.
        """
        mode: dict[str, object] = (
            {"exact_quantiles": True} if self.exact_quantiles else {"relative_accuracy": self.sketch.relative_accuracy}
        )
        return {**super()._setting_items(), "two_sided": self.two_sided, **mode}

    @property
    def _sketch(self) -> QuantileSketch | None:
        """The quantile sketch, or ``None`` for exact quantiles."""
        return None if self.exact_quantiles else self.sketch

    def _accumulate_directed(self, r: DirectedDistances) -> None:
        self._forward_states.update(self, r.forward, self._sketch)
        if self.two_sided and r.reverse is not None:
            self._reverse_states.update(self, r.reverse, self._sketch)
        if r.peak.numel():
            self._update_peak(r.peak.max())

    def _update_peak(self, peak: Tensor | float) -> None:
        p = torch.as_tensor(peak, dtype=torch.float64).to(self.reference_peak.device)
        self.reference_peak = torch.maximum(self.reference_peak, p)

    def _peak(self) -> float | None:
        if self.fixed_peak is not None:
            return self.fixed_peak
        p = float(self.reference_peak)
        return derived_peak(p, "reference (the largest diagonal measured)") if p >= 0 else None

    def compute_statistics(self) -> dict[str, DistanceStatistics]:
        """The accumulated :class:`DistanceStatistics` per direction: ``{"forward": ..., "reverse": ...}``."""
        sketch, peak = self._sketch, self._peak()
        out = {
            "forward": self._forward_states.compute(
                self, sketch, what="simplified → reference", ddof=self.ddof, peak=peak
            )
        }
        if self.two_sided:
            out["reverse"] = self._reverse_states.compute(
                self, sketch, what="reference → simplified", ddof=self.ddof, peak=peak
            )
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

    def statistic(self, key: str, *, label: str | None = None) -> SelectedStatistic:
        """A scalar metric reporting ``self.compute()[key]``, for ``self.log(name, metric)`` in Lightning.

        The view shares this metric's accumulation: keep calling ``update`` on this metric; logging the view makes
        Lightning compute it at the end of the epoch and reset this metric. See
        :class:`~torchmeshmetric.metrics.SelectedStatistic`.

        Args:
            key: one of :meth:`statistic_names`.
            label: the name ``plot()`` gives the value (default ``key``).

        Raises:
            ValueError: ``key`` is not one of :meth:`statistic_names`.
        """
        return SelectedStatistic(self, key, label=label)

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
        # each view's plot() is named by its key as the collection names it (prefix and postfix included)
        views: dict[str, Metric | MetricCollection] = {
            k: self.statistic(k, label=f"{prefix or ''}{k}{postfix or ''}") for k in keys
        }
        return MetricCollection(views, prefix=prefix, postfix=postfix, compute_groups=False)

    def compute(self) -> dict[str, Tensor]:
        """Dict of 0-dim float64 tensors (``count`` included, as float64, so that every value logs as a float).

        Raises:
            EmptyInputError: nothing was accumulated in a reported direction.
        """
        stats = self.compute_statistics()
        out: dict[str, Tensor] = {}
        for key, prefix in (("forward", ""), ("reverse", "reverse_")):
            if key in stats:
                out.update({prefix + name: value for name, value in stats[key].as_tensors().items()})
        if self.two_sided:
            f, r = stats["forward"], stats["reverse"]
            out["symmetric_ave"] = 0.5 * (f.ave + r.ave)
            out["hausdorff"] = torch.maximum(f.max, r.max)
            out["symmetric_mse"] = torch.maximum(f.mse, r.mse)
            # The side with the larger mse (by rmse where both sums of squares overflowed): its rmse and PSNR, which
            # stay finite where the mse overflows (see distance_statistics); sqrt(max) is that rmse bit for bit.
            forward = (f.mse > r.mse) | ((f.mse == r.mse) & (f.rmse >= r.rmse))
            out["symmetric_rmse"] = torch.where(forward, f.rmse, r.rmse)
            if f.psnr is not None and r.psnr is not None:
                out["symmetric_psnr"] = torch.where(forward, f.psnr, r.psnr)
        return out


def _checked_peak(peak: object) -> Tensor:
    """``update``'s ``peak`` (a number, or a tensor of them): the largest, once every one is finite and > 0.

    A NaN peak stuck for good (the running maximum of NaN stays NaN) and a negative one was dropped in silence.
    """
    if isinstance(peak, bool) or not isinstance(peak, (numbers.Real, Tensor)):  # numpy's numbers are Real
        raise TypeError(f"peak: expected a number or a tensor of them, found {type(peak).__name__} {peak!r}")
    # A Python number straight to float64: torch's default float32 made a peak of 1e200 inf (refused).
    p = peak.detach() if isinstance(peak, Tensor) else torch.as_tensor(peak, dtype=torch.float64)
    if p.dtype == torch.bool or p.is_complex() or p.numel() == 0:
        raise TypeError(f"peak: expected real numbers, found a {p.dtype} tensor of {p.numel()} values")
    p = p.to(torch.float64)
    if not bool((torch.isfinite(p) & (p > 0)).all()):
        raise ValueError(f"peak: expected finite values > 0, found {p.flatten()[:4].tolist()}")
    return p.max()


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
        """Accumulate ``(N,)`` forward distances (and ``(R,)`` reverse ones when ``two_sided``).

        Every argument is checked before any state changes: a refused update leaves the metric as it was (a bad
        ``reverse_dists`` once left the forward distances counted and the reverse ones not).

        Raises:
            TypeError: ``reverse_dists`` given one-sided or missing two-sided; ``peak`` not a number.
            ValueError: ``peak`` not finite and > 0; bad distances (see
                :func:`~torchmeshmetric.stats.distance_statistics_update`).
        """
        if self.two_sided and reverse_dists is None:
            raise TypeError("reverse_dists: expected a (R,) tensor because two_sided=True, found None")
        if not self.two_sided and reverse_dists is not None:
            raise TypeError("reverse_dists: only valid with two_sided=True")
        if peak is not None:
            peak = _checked_peak(peak)
        updates = [(self._forward_states, dists, distance_statistics_update(dists, self._sketch, "dists"))]
        if reverse_dists is not None:
            check_shape(reverse_dists, ("R",), "reverse_dists")
            reverse = distance_statistics_update(reverse_dists, self._sketch, "reverse_dists")
            updates.append((self._reverse_states, reverse_dists, reverse))
        for states, values, (moments, quantile_data) in updates:  # all checked above: none added without the others
            if values.numel():
                states.add(self, moments, quantile_data, self._sketch)
        if peak is not None:
            self._update_peak(peak)


class MeasuredDistanceBase(DistanceStatisticsBase):
    """Base of the metrics that measure their own distances: ``update(simplified, reference)``.

    A subclass names its distance-sets function (``_distance_sets``, e.g.
    :func:`~torchmeshmetric.metrics.mesh_surface_distance_sets`) and sets ``_options``, the function's keyword
    arguments besides ``two_sided``, in its ``__init__``.
    """

    _distance_sets: Callable[..., DirectedDistances]
    _options: dict[str, Any]

    def update(self, simplified: Any, reference: Any) -> None:
        """Measure a simplified mesh (or point set), or a list of them, against the reference(s)."""
        with torch.no_grad():
            r = self._distance_sets(simplified, reference, two_sided=self.two_sided, **self._options)
        self._accumulate_directed(r)
