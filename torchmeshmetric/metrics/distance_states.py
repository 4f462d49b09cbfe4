"""The ``torchmetrics`` states that accumulate one distance set: exact, mergeable and DDP-synchronised.

A metric declares, per distance set it accumulates, a :class:`DistanceStates` naming its states; the states hold
what :func:`~torchmeshmetric.stats.statistics.distance_statistics_update` returns for every batch:

- ``moments``: one ``(1, 6)`` float64 row of :class:`~torchmeshmetric.stats.moments.Moments` (an empty set's row
  before any update), reduced by :func:`merge_moment_rows`. Every update merges its batch into the row (Chan et al.
  1979); a DDP sync, a ``forward()`` and ``merge_state`` merge the rows they meet with the same formula, so the state
  has the same shape on every process (torchmetrics stacks what it gathers: rows of ``cat`` states counted per
  update, 2 on one process and 0 on another, stopped the sync). This is exact: no state is averaged, and no
  ``E[d^2] - E[d]^2`` appears.
- ``values``: the distances themselves (a list state, ``"cat"``), for exact quantiles; or
- ``sketch``: the ``(num_bins,)`` counts of a :class:`~torchmeshmetric.stats.sketch.QuantileSketch` (``"sum"``),
  for quantiles within a relative error in constant memory.

All states are float64 (``Metric.half()``/``.float()`` leave them alone unless ``set_dtype`` is used). A metric
holding such states derives from :class:`DistanceStatesMetric`, which keeps them whole where torchmetrics would not
(a process that saw no distance, a ``forward()`` whose batch is refused).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import torch
from torch import Tensor
from torchmetrics import Metric
from torchmetrics.utilities.data import dim_zero_cat
from torchmetrics.utilities.distributed import gather_all_tensors

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.metrics._settings import SettingsMetric
from torchmeshmetric.stats.moments import Moments, merge_into_row, merge_rows, moments_rows
from torchmeshmetric.stats.sketch import QuantileSketch
from torchmeshmetric.stats.statistics import (
    DistanceStatistics,
    distance_statistics_compute,
    distance_statistics_update,
)

__all__ = ["DistanceStates", "DistanceStatesMetric", "merge_moment_rows"]

_EMPTY_ROW = moments_rows(merge_rows(torch.zeros(0, len(Moments._fields), dtype=torch.float64)))


def merge_moment_rows(rows: Tensor) -> Tensor:
    """The ``(1, 6)`` row of moments rows of any leading shape (``(K, 1, 6)`` as torchmetrics stacks them).

    The ``dist_reduce_fx`` of a moments state: the exact merge of :func:`~torchmeshmetric.stats.moments.merge_rows`.

    Example:
        >>> from torchmeshmetric.stats.moments import moments_of, moments_rows
        >>> a, b = moments_rows(moments_of(torch.tensor([1.0, 2.0]))), moments_rows(moments_of(torch.tensor([6.0])))
        >>> merge_moment_rows(torch.stack([a, b]))[0, :2].tolist()
        [3.0, 3.0]
    """
    return moments_rows(merge_rows(rows.reshape(-1, len(Moments._fields))))


class DistanceStates(NamedTuple):
    """The names of the states of one distance set in a ``torchmetrics.Metric``, and the operations on them.

    Declared as class constants by each metric, so that every state name is written out once in the source.

    Attributes:
        moments: the ``(1, 6)`` moments row state.
        values: the list-of-distances state (exact quantiles).
        sketch: the sketch-counts state (sketched quantiles); ``None`` where the metric has no sketch mode.

    Example:
        >>> import torch
        >>> from torchmetrics import Metric
        >>> class Pool(Metric):
        ...     STATES = DistanceStates("pool_moments", "pool_values")
        ...     def __init__(self):
        ...         super().__init__()
        ...         self.STATES.add_to(self, sketch=None)
        ...     def update(self, dists):
        ...         self.STATES.update(self, dists, sketch=None)
        ...     def compute(self):
        ...         return self.STATES.compute(self, sketch=None, what="pooled").ave
        >>> pool = Pool()
        >>> pool.update(torch.tensor([1.0, 2.0]))
        >>> pool.update(torch.tensor([6.0]))
        >>> pool.compute()
        tensor(3., dtype=torch.float64)
    """

    moments: str
    values: str
    sketch: str | None = None

    def add_to(self, metric: Metric, sketch: QuantileSketch | None) -> None:
        """Declare the states on ``metric`` (in its ``__init__``): values for ``sketch=None``, else sketch counts."""
        f64 = torch.float64
        metric.add_state(self.moments, default=_EMPTY_ROW.clone(), dist_reduce_fx=merge_moment_rows)
        if sketch is None:
            metric.add_state(self.values, default=[], dist_reduce_fx="cat")
        else:
            metric.add_state(self._sketch_name(), default=torch.zeros(sketch.num_bins, dtype=f64), dist_reduce_fx="sum")

    def update(self, metric: Metric, dists: Tensor, sketch: QuantileSketch | None, name: str = "dists") -> None:
        """Add a ``(N,)`` tensor of distances (``N = 0`` changes nothing); ``name`` is the argument's, for errors.

        Raises:
            ShapeError, TypeError, NonFiniteError: see
                :func:`~torchmeshmetric.stats.statistics.distance_statistics_update`.
        """
        moments, quantile_data = distance_statistics_update(dists, sketch, name)
        if dists.numel():
            self.add(metric, moments, quantile_data, sketch)

    def add(self, metric: Metric, moments: Moments, quantile_data: Tensor, sketch: QuantileSketch | None) -> None:
        """Add what :func:`~torchmeshmetric.stats.statistics.distance_statistics_update` returned for a set.

        Apart from :meth:`update` so that a metric taking several sets checks them all before it adds any. An
        empty set is not added (its caller knows its size without a device sync).
        """
        rows: Tensor = getattr(metric, self.moments)
        setattr(metric, self.moments, merge_into_row(rows, moments))
        if sketch is None:
            getattr(metric, self.values).append(quantile_data.to(rows.device))
        else:
            name = self._sketch_name()
            setattr(metric, name, getattr(metric, name) + quantile_data.to(rows.device))

    def num_distances(self, metric: Metric) -> Tensor:
        """Number of distances accumulated (0-dim float64; this process's only, unless synchronised)."""
        rows: Tensor = getattr(metric, self.moments)
        return rows[:, 0].sum()

    def compute(
        self,
        metric: Metric,
        sketch: QuantileSketch | None,
        *,
        what: str,
        ddof: int = 0,
        peak: float | Tensor | None = None,
    ) -> DistanceStatistics:
        """The statistics of everything accumulated (all rows merged).

        Args:
            metric: the metric holding the states.
            sketch: the sketch given to :meth:`add_to`.
            what: the set's name in the error message (e.g. ``"simplified → reference"``).
            ddof: delta degrees of freedom of ``var``/``std``.
            peak: PSNR peak, or ``None``.

        Raises:
            EmptyInputError: no distance was accumulated.
        """
        if float(self.num_distances(metric)) == 0:
            raise EmptyInputError(
                f"{type(metric).__name__}.compute: no {what} distances were accumulated; call update() with "
                "non-empty inputs first"
            )
        moments = merge_rows(getattr(metric, self.moments))
        quantile_data = (
            dim_zero_cat(getattr(metric, self.values)) if sketch is None else getattr(metric, self._sketch_name())
        )
        return distance_statistics_compute(moments, quantile_data, sketch=sketch, ddof=ddof, peak=peak)

    def _sketch_name(self) -> str:
        if self.sketch is None:
            raise TypeError(f"{self.moments}: this metric declares no sketch state (exact quantiles only)")
        return self.sketch


class DistanceStatesMetric(SettingsMetric):
    """A ``torchmetrics.Metric`` whose states are :class:`DistanceStates`: kept whole where torchmetrics would not.

    A :class:`~torchmeshmetric.metrics._settings.SettingsMetric`: its settings keep it out of the compute groups and
    merges of other configurations.

    - ``forward()`` whose batch is refused or empty (its batch ``compute`` raises) leaves the accumulated states as
      they were: torchmetrics resets them to compute the batch's value, and an error lost every earlier update.
    - A DDP sync from a process that accumulated no distance sends an empty float64 list of values: torchmetrics
      sent one of the metric's default dtype (float32), and gloo aborted the process on the size mismatch.
    """

    def forward(self, *args: Any, **kwargs: Any) -> Any:
        """``Metric.forward`` (the batch's value, accumulated), with the states restored when it raises."""
        # reset() empties list states in place and replaces tensors: a shallow copy of each list keeps them all
        saved = {k: list(v) if isinstance(v, list) else v for k, v in ((k, getattr(self, k)) for k in self._defaults)}
        context = (self._update_count, self._computed, self._to_sync, self._should_unsync, self.compute_on_cpu)
        try:
            return super().forward(*args, **kwargs)
        except BaseException:
            for k, v in saved.items():
                setattr(self, k, v)
            self._update_count, self._computed, self._to_sync, self._should_unsync, self.compute_on_cpu = context
            self._enable_grad = False
            raise

    def _one_row(self, states: dict[str, Any]) -> dict[str, Any]:
        """``states`` with every moments state of several rows merged into one.

        Checkpoints written before 2026-12-07 kept one row per ``forward()`` call and per DDP process, which a sync
        or a merge can no longer stack.
        """
        merged = dict(states)
        for name, reduce in self._reductions.items():
            value = merged.get(name)
            if reduce is merge_moment_rows and isinstance(value, Tensor) and value.dim() == 2 and value.shape[0] != 1:
                merged[name] = merge_moment_rows(value.to(torch.float64))
        return merged

    def _load_from_state_dict(
        self,
        state_dict: dict,
        prefix: str,
        local_metadata: dict,
        strict: bool,
        missing_keys: list[str],
        unexpected_keys: list[str],
        error_msgs: list[str],
    ) -> None:
        super()._load_from_state_dict(
            state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys, error_msgs
        )
        for name, value in self._one_row({k: getattr(self, k) for k in self._defaults}).items():
            setattr(self, name, value)

    def merge_state(self, incoming_state: dict[str, Any] | Metric) -> None:
        """``SettingsMetric.merge_state``, an incoming dict's moments (and this metric's) merged to one row first.

        Raises:
            ValueError: a metric of other settings, or a dict of other states (see
                :class:`~torchmeshmetric.metrics._settings.SettingsMetric`).
        """
        for name, value in self._one_row({k: getattr(self, k) for k in self._defaults}).items():
            setattr(self, name, value)
        if isinstance(incoming_state, dict):
            incoming_state = self._one_row(incoming_state)
        super().merge_state(incoming_state)

    def _sync_dist(self, dist_sync_fn: Callable = gather_all_tensors, process_group: Any | None = None) -> None:
        for name, default in self._defaults.items():  # the lists are the distances: float64, like every state here
            if isinstance(default, list) and not getattr(self, name):
                setattr(self, name, [torch.zeros(0, dtype=torch.float64, device=self.device)])
        super()._sync_dist(dist_sync_fn, process_group)
