"""One statistic of a distance metric as a scalar ``torchmetrics.Metric``: what ``Lightning``'s ``self.log`` accepts.

Lightning logs a ``Metric`` object (``self.log(name, metric)``, ``self.log_dict(collection)``) only when its
``compute()`` returns one tensor, while :class:`~torchmeshmetric.metrics.MeshSurfaceDistance` and its siblings
return a dict of statistics. :class:`SelectedStatistic` is a read-only view of one key of that dict: it holds no
state of its own, so every view of a metric shares the metric's single accumulation (the distances are computed
once per ``update``, however many statistics are logged), its DDP synchronisation, and its float64 precision.
"""

from __future__ import annotations

from typing import Any, Protocol

from torch import Tensor
from torchmetrics import Metric

from torchmeshmetric.metrics._plot import StatisticsPlot

__all__ = ["SelectedStatistic", "StatisticSource"]


class StatisticSource(Protocol):
    """What a view needs of its source, a :class:`~torchmeshmetric.metrics.DistanceStatisticsBase`.

    Typed here so that the view does not import the metric that makes it (no import circle).
    """

    _update_count: int

    def statistic_names(self) -> tuple[str, ...]:
        """The keys of the source's ``compute()``."""
        ...

    def compute(self) -> Any:
        """The source's statistics, by key."""
        ...

    def reset(self) -> None:
        """Reset the source's state."""
        ...


class SelectedStatistic(StatisticsPlot, Metric):
    """The 0-dim tensor ``source.compute()[key]``, as a metric that Lightning can log and reset.

    Made by :meth:`DistanceStatisticsBase.statistic` (or, for several keys at once, by
    :meth:`DistanceStatisticsBase.statistics`). The view never accumulates: update the *source* metric (once per
    batch), then compute or log the views. Its step value (what Lightning logs with ``on_step=True``) is the
    source's batch value of ``key`` when the source was called (``forward``: ``metric(simplified, reference)``);
    after ``update()`` alone a step has no value and Lightning logs the epoch value only, as for any metric.
    ``compute()`` is not cached, so it always reflects the source's current
    state; the source caches its own result until its next ``update``/``reset``. ``reset()`` resets the source
    (Lightning resets every logged metric at the end of an epoch; resetting a shared source several times is
    harmless). ``plot()`` draws the value (or a list of values, one a step) as torchmetrics draws a scalar
    metric. ``update()`` is not supported (it would be ambiguous which of several views feeds the source).

    Args:
        source: the metric whose statistic is reported.
        key: a key of ``source.compute()`` (one of ``source.statistic_names()``).
        label: the name ``plot()`` gives the value (its axis label; default ``key``;
            :meth:`~torchmeshmetric.metrics.DistanceStatisticsBase.statistics` gives the collection's name of it,
            prefix and postfix included).

    Example:
        >>> import torch
        >>> from torchmeshmetric.metrics import DistanceStatisticsMetric
        >>> metric = DistanceStatisticsMetric()
        >>> rmse = metric.statistic("rmse")
        >>> metric.update(torch.tensor([3.0, 4.0]))
        >>> rmse.compute()
        tensor(3.5355, dtype=torch.float64)
        >>> rmse.plot()[1].get_ylabel()
        'rmse'
    """

    is_differentiable = False
    # Depends on the key (psnr: higher is better; distances: lower), and torchmetrics makes it a class constant.
    higher_is_better: bool | None = None
    full_state_update = False

    def __init__(self, source: StatisticSource, key: str, *, label: str | None = None) -> None:
        super().__init__(compute_with_cache=False)
        names = source.statistic_names()
        if key not in names:
            raise ValueError(f"key: expected one of {names} for this {type(source).__name__}, found {key!r}")
        if label is not None and not isinstance(label, str):
            raise TypeError(f"label: expected a string or None, found {type(label).__name__} {label!r}")
        self.source = source
        self.key = key
        self.label = key if label is None else label

    # The view has no state: its "update count" is the source's, so torchmetrics does not warn that compute() ran
    # before update() when the source was updated.
    @property
    def _update_count(self) -> int:
        return int(self.source._update_count) if "source" in self._modules else 0

    @_update_count.setter
    def _update_count(self, value: int) -> None:
        pass  # Metric.__init__/reset assign it; the source keeps the real count

    # The step value: the source's batch value of the key, when the source's forward() ran. Lightning logs a metric
    # for a step (self.log(..., on_step=True), its default in training_step) from its `_forward_cache`; a view never
    # runs forward, so it logged nothing, silently (found by review). After update() alone there is no batch value,
    # as for any torchmetrics metric: Lightning then logs the epoch value only.
    @property
    def _forward_cache(self) -> Any:
        cache = getattr(self.source, "_forward_cache", None) if "source" in self._modules else None
        return cache.get(self.key) if isinstance(cache, dict) else None

    @_forward_cache.setter
    def _forward_cache(self, value: Any) -> None:
        pass  # Metric.__init__/reset assign it; the source keeps the batch value

    def update(self, *args: Any, **kwargs: Any) -> None:
        """Not supported: update the source metric instead (once per batch, for all of its views).

        Raises:
            TypeError: always.
        """
        raise TypeError(
            f"SelectedStatistic({self.key!r}).update: a view accumulates nothing; call update() on the source "
            f"{type(self.source).__name__} once per batch instead"
        )

    def compute(self) -> Tensor:
        """``source.compute()[key]``: a 0-dim float64 tensor, synchronised across processes by the source.

        Raises:
            EmptyInputError: the source has accumulated nothing (see the source's ``compute``).
        """
        return self.source.compute()[self.key]

    def reset(self) -> None:
        """Reset the source metric (and this view's bookkeeping)."""
        self.source.reset()
        super().reset()

    def _plot_higher_is_better(self) -> bool:
        """A PSNR is better higher, a distance lower (``plot()``'s optimal-value mark)."""
        return "psnr" in self.key

    def _plot_name(self) -> str:
        """The statistic shown (``plot()``'s axis label; every view was labelled ``SelectedStatistic``)."""
        return self.label

    def extra_repr(self) -> str:
        """The selected key (shown in ``repr``)."""
        return f"key={self.key!r}"
