"""``plot()`` of the metric classes, in torchmetrics' convention: ``fig, ax = metric.plot()``.

torchmetrics gives every metric ``plot(val=None, ax=None)`` returning ``(fig, ax)`` (``fig`` is ``None`` when an
``ax`` was given), drawn with matplotlib, which stays optional: it is imported when ``plot`` is called, and a missing
matplotlib is torchmetrics' own ``ModuleNotFoundError``. A metric of this package computes a dict of statistics (or,
for a :class:`~torchmeshmetric.metrics.SelectedStatistic`, one of them), so :class:`StatisticsPlot`, shared by every
metric class, draws

* one result (``compute()``'s dict) as bars: one bar a statistic, all in the unit of the distances (``var``/``mse``
  are squared, ``psnr`` is in dB and ``count`` is a number: they are left out unless named in ``keys``);
* several results (a list of dicts, one a step or epoch) as curves, one a statistic, with torchmetrics'
  ``plot_single_or_multi_val``;
* a scalar (a tensor, or a list of them) exactly as torchmetrics draws a scalar metric.

A value that is not finite (a NaN, a PSNR of ``inf`` between equal meshes) cannot be drawn: a bar's label shows it
over no bar, a curve has no point there, and a ``UserWarning`` names each such value (matplotlib alone drops them
without a word).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import torch
from torch import Tensor

__all__ = ["LENGTH_STATISTICS", "StatisticsPlot", "length_keys"]

#: Statistics in the unit of the distances (the keys :meth:`StatisticsPlot.plot` draws by default).
LENGTH_STATISTICS: tuple[str, ...] = ("ave", "std", "rmse", "median", "p95", "p99", "max", "min")
_SYMMETRIC_LENGTHS = ("symmetric_ave", "symmetric_rmse", "hausdorff")


def length_keys(keys: Sequence[str]) -> list[str]:
    """The keys of ``keys`` that are lengths (forward, ``reverse_`` and symmetric), in ``keys``' order.

    Example:
        >>> length_keys(["ave", "var", "mse", "rmse", "count", "psnr", "reverse_max", "hausdorff"])
        ['ave', 'rmse', 'reverse_max', 'hausdorff']
    """
    return [k for k in keys if _base(k).removeprefix("reverse_") in LENGTH_STATISTICS or _base(k) in _SYMMETRIC_LENGTHS]


def _base(key: str) -> str:
    """The statistic of a key, without the set of a flattened key (``"surface_k/ave"`` -> ``"ave"``)."""
    return key.rsplit("/", 1)[-1]


def _direction(key: str) -> int:
    """Colour index of a key: 0 forward, 1 reverse, 2 symmetric."""
    if key.startswith("reverse"):
        return 1
    return 2 if _base(key) in _SYMMETRIC_LENGTHS or _base(key).startswith("symmetric_") else 0


class StatisticsPlot:
    """Mixin giving a ``torchmetrics.Metric`` of this package its ``plot``; see the module docstring.

    The metric provides ``compute()`` and ``higher_is_better``; a scalar metric whose direction depends on its
    statistic (a :class:`~torchmeshmetric.metrics.SelectedStatistic`) overrides :meth:`_plot_higher_is_better`.
    """

    higher_is_better: bool | None
    compute: Callable[[], Any]  # the metric's own (declared only: the mixin comes before Metric in the bases)

    def _plot_keys(self, result: dict[str, Tensor]) -> list[str]:
        """The keys of a dict result drawn when ``plot`` is given no ``keys``: those in the distances' unit."""
        return length_keys(list(result))

    def _plot_result(self, result: Any) -> dict[str, Tensor]:
        """A result as a flat ``{key: 0-dim tensor}`` (a metric with a nested result flattens it here)."""
        return dict(result)

    def _plot_higher_is_better(self) -> bool | None:
        """Whether a larger scalar is better (``None``: unknown), for torchmetrics' "optimal value" mark."""
        return self.higher_is_better

    def plot(
        self,
        val: Tensor | Sequence[Tensor] | dict[str, Tensor] | Sequence[dict[str, Tensor]] | None = None,
        ax: Any | None = None,
        *,
        keys: Sequence[str] | None = None,
    ) -> tuple[Any, Any]:
        """Plot a result of the metric (default: ``self.compute()``), or a list of them as curves over steps.

        Args:
            val: a result of ``compute()`` / ``forward()``, a list of them (one per step), or ``None`` to plot
                ``self.compute()``.
            ax: a ``matplotlib.axes.Axes`` to draw into (default: a new figure).
            keys: the statistics of a dict result to draw (default: those in the unit of the distances,
                :func:`length_keys`).

        Returns:
            ``(fig, ax)``: the new ``matplotlib.figure.Figure`` (``None`` when ``ax`` was given) and the axes.

        Raises:
            ModuleNotFoundError: matplotlib is not installed.
            KeyError: a key of ``keys`` is not in the result (or, for a list of results, in one of them).
            TypeError: ``keys`` is a string, not a list of names.
            ValueError: ``val`` is none of the accepted forms, or an empty list.

        Example:
            >>> import torch
            >>> from torchmeshmetric.metrics import DistanceStatisticsMetric
            >>> metric = DistanceStatisticsMetric()
            >>> metric.update(torch.tensor([1.0, 2.0, 6.0]))
            >>> fig, ax = metric.plot()
            >>> [t.get_text() for t in ax.get_xticklabels()][:3]
            ['ave', 'std', 'rmse']
        """
        from torchmetrics.utilities.plot import _error_on_missing_matplotlib

        _error_on_missing_matplotlib()
        val = self.compute() if val is None else val
        name = type(self).__name__
        if isinstance(val, dict):
            flat = self._plot_result(val)
            return _bars(flat, ax, self._chosen(flat, keys), name)
        if isinstance(val, Sequence) and not isinstance(val, str) and len(val) == 0:
            raise ValueError("val: expected a result or a non-empty list of results, found an empty list")
        if isinstance(val, Sequence) and isinstance(val[0], dict):
            steps = [self._plot_result(step) for step in val]
            chosen = self._chosen(steps[0], keys)
            for i, step in enumerate(steps[1:], start=1):
                if missing := [k for k in chosen if k not in step]:
                    raise KeyError(f"val[{i}]: {missing} not in this step's result, whose keys are {list(step)}")
            return _curves([{k: step[k] for k in chosen} for step in steps], ax, name, None)
        return _curves(val, ax, name, self._plot_higher_is_better())

    def _chosen(self, result: dict[str, Tensor], keys: Sequence[str] | None) -> list[str]:
        if isinstance(keys, str):  # list("ave") would be ["a", "v", "e"]
            raise TypeError(f"keys: expected a list of statistic names, found the string {keys!r} (write [{keys!r}])")
        chosen = self._plot_keys(result) if keys is None else list(keys)
        missing = [k for k in chosen if k not in result]
        if missing:
            raise KeyError(f"keys: {missing} not in the result, whose keys are {list(result)}")
        if not chosen:
            raise ValueError(f"keys: nothing to plot among {list(result)}")
        return chosen


def _warn_not_finite(name: str, found: list[str], drawn: str) -> None:
    """Say which values cannot be drawn (matplotlib leaves a NaN out and an infinity off the axes without a word)."""
    if found:
        shown = ", ".join(found[:5]) + (f" and {len(found) - 5} more" if len(found) > 5 else "")
        warnings.warn(f"{name}.plot: {shown} not finite: {drawn}", UserWarning, stacklevel=4)  # the caller of plot


def _not_finite_steps(val: Any) -> list[str]:
    """``"key[step]=value"`` (or ``"[step]=value"``) of every non-finite value of a result, or of a list of them."""
    steps = val if isinstance(val, Sequence) else [val]
    out = []
    for i, step in enumerate(steps):
        for key, v in step.items() if isinstance(step, dict) else [("val", step)]:
            x = v.detach().double().reshape(-1) if isinstance(v, Tensor) else torch.tensor([float(v)])
            where = f"[{i}]" if steps is val else ""
            out += [f"{key}{where}={float(x[j]):g}" for j in torch.nonzero(~torch.isfinite(x)).reshape(-1).tolist()]
    return out


def _curves(val: Any, ax: Any, name: str, higher_is_better: bool | None) -> tuple[Any, Any]:
    """Draw with torchmetrics' own helper of a scalar, a list of scalars or a list of dicts (curves over steps)."""
    from torchmetrics.utilities.plot import plot_single_or_multi_val

    _warn_not_finite(name, _not_finite_steps(val), "the curves have no point there")
    lower = None if higher_is_better else 0.0  # distances are >= 0; a PSNR has no lower bound
    fig, ax = plot_single_or_multi_val(val, ax=ax, higher_is_better=higher_is_better, lower_bound=lower, name=name)
    return fig, ax


def _bars(result: dict[str, Tensor], ax: Any, chosen: list[str], name: str) -> tuple[Any, Any]:
    """One bar a statistic (colour: forward, reverse, symmetric), each labelled with its value."""
    import matplotlib.pyplot as plt

    values = [float(result[k]) for k in chosen]
    finite = [v if math.isfinite(v) else 0.0 for v in values]  # a NaN bar had no label at all, an inf one no height
    odd = [f"{k}={v:g}" for k, v in zip(chosen, values, strict=True) if not math.isfinite(v)]
    _warn_not_finite(name, odd, "each is a label over no bar")
    fig, ax = plt.subplots(figsize=(max(4.0, 0.6 * len(chosen) + 1.5), 3.5)) if ax is None else (None, ax)
    bars = ax.bar(range(len(chosen)), finite, color=[f"C{_direction(k)}" for k in chosen])
    ax.bar_label(bars, labels=[f"{v:.3g}" for v in values], fontsize=7)
    tilted = len(chosen) > 8
    ax.set_xticks(range(len(chosen)), chosen, rotation=45 if tilted else 0, ha="right" if tilted else "center")
    ax.set_ylabel(name)
    if min(finite) >= 0:
        ax.set_ylim(bottom=0.0)  # distances: the bars start at their lower bound
    ax.grid(True, axis="y")
    return fig, ax
