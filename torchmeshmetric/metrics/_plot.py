"""``plot()`` of the metric classes, in torchmetrics' convention: ``fig, ax = metric.plot()``.

torchmetrics gives every metric ``plot(val=None, ax=None)`` returning ``(fig, ax)`` (``fig`` is ``None`` when an
``ax`` was given), drawn with matplotlib, which stays optional: it is imported when ``plot`` is called, and a missing
matplotlib is torchmetrics' own ``ModuleNotFoundError``. A metric of this package computes a dict of statistics (or,
for a :class:`~torchmeshmetric.metrics.SelectedStatistic`, one of them), so :class:`StatisticsPlot`, shared by every
metric class, draws

* one result (``compute()``'s dict) as bars: one bar a statistic, all in the unit of the distances (``var``/``mse``
  are squared, ``psnr`` is in dB and ``count`` is a number: they are left out unless named in ``keys``), each
  labelled with the digits the reports print (:func:`bar_label`: 2 significant digits, 3 for a maximum, one decimal
  of a PSNR);
* several results (a list of dicts, one a step or epoch) as curves, one a statistic, with torchmetrics'
  ``plot_single_or_multi_val``;
* a scalar (a number or a one-element tensor, or a list of them) exactly as torchmetrics draws a scalar metric,
  its axis named by the metric (a :class:`~torchmeshmetric.metrics.SelectedStatistic` by its key).

Any other ``val`` is refused with a ``ValueError`` naming ``val`` (and the step or key that does not fit).

A value that is not finite (a NaN, a PSNR of ``inf`` between equal meshes) cannot be drawn: a bar's label shows it
over no bar, a curve has no point there, and a ``UserWarning`` names each such value (matplotlib alone drops them
without a word).
"""

from __future__ import annotations

import math
import numbers
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import torch
from torch import Tensor

from torchmeshmetric._format import format_number, plain_label

__all__ = ["LENGTH_STATISTICS", "StatisticsPlot", "bar_label", "length_keys"]

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


def bar_label(key: str, value: float) -> str:
    """A bar's label: ``value`` with the digits the reports print of its statistic.

    The tables print 2 significant digits of a mean, spread or quantile (those the input determines), 3 of a
    maximum (a Hausdorff distance, a minimum: an extreme too) and one decimal of a PSNR; a count is a whole number.
    A flattened key of :class:`~torchmeshmetric.evaluation.TemporalConsistency` (``"surface_k_minus_1/ave"``,
    ``"flicker/max"``, ``"registration/residual/rmse"``) prints the digits of its statistic, whatever its set: the
    tables print the same digits in every row (:func:`~torchmeshmetric.evaluation.reports.statistic_cell`).

    Example:
        >>> bar_label("ave", 1.5), bar_label("reverse_std", 0.5), bar_label("hausdorff", 2.0), bar_label("psnr", 61.234)
        ('1.5', '0.50', '2.00', '61.2')
        >>> bar_label("surface_k/rmse", 0.0158), bar_label("surface_k_minus_1/rmse", 0.0158)
        ('0.016', '0.016')
    """
    from torchmeshmetric.evaluation.reports import statistic_cell  # on use only (the tables' digits)

    statistic = _base(key).removeprefix("reverse_").removeprefix("symmetric_")
    if statistic == "count":
        return format_number(value, ".0f")
    if "psnr" in statistic:
        column = "psnr"
    elif statistic in ("max", "min", "hausdorff"):
        column = "max"
    else:  # ave, var, std, mse, rmse and the quantiles (median, p95, p99: P95's digits)
        column = statistic if statistic in ("ave", "var", "std", "mse", "rmse") else "p95"
    return statistic_cell(value, column)


def _scalar(value: object, where: str) -> Tensor:
    """A value of a result as a 0-dim tensor: a real number or a one-element tensor; else an error naming it."""
    if isinstance(value, Tensor) and value.numel() == 1 and not value.dtype.is_complex:
        return value.detach().reshape(())
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return torch.tensor(float(value), dtype=torch.float64)
    found = (
        f"a tensor of shape {tuple(value.shape)}"
        if isinstance(value, Tensor)
        else f"{type(value).__name__} {value!r:.40}"
    )
    raise ValueError(f"{where}: expected a number or a one-element tensor, found {found}")


def _result(value: object, where: str) -> dict[str, Tensor]:
    """A dict result with every value a 0-dim tensor (``{"ave": tensor([1., 2.])}`` named, not a bare error)."""
    return {k: _scalar(v, f"{where}[{k!r}]") for k, v in value.items()}  # type: ignore[attr-defined]


def _forms(val: object) -> tuple[str, Any]:
    """``val`` in one of the accepted forms: ``"result"``, ``"results"``, ``"scalar"`` or ``"scalars"``, and its value.

    Anything else is a ``ValueError`` naming ``val``.
    """
    if isinstance(val, dict):
        return "result", val
    if isinstance(val, Tensor) or (isinstance(val, numbers.Real) and not isinstance(val, bool)):
        return "scalar", _scalar(val, "val")
    if isinstance(val, Sequence) and not isinstance(val, (str, bytes)):
        if len(val) == 0:
            raise ValueError("val: expected a result or a non-empty list of results, found an empty list")
        if all(isinstance(step, dict) for step in val):
            return "results", list(val)
        if not any(isinstance(step, dict) for step in val):
            return "scalars", [_scalar(step, f"val[{i}]") for i, step in enumerate(val)]
        raise ValueError("val: expected a list of results (dicts) or of scalars, found a list mixing both")
    raise ValueError(
        "val: expected a result (a dict of statistics), a scalar (a number or a one-element tensor), a non-empty "
        f"list of either, or None; found {type(val).__name__} {val!r:.40}"
    )


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

    def _plot_name(self) -> str:
        """The label of the plot's value axis and of its warnings: the class' name (a view: its statistic)."""
        return type(self).__name__

    def plot(
        self,
        val: Tensor | Sequence[Tensor] | dict[str, Tensor] | Sequence[dict[str, Tensor]] | None = None,
        ax: Any | None = None,
        *,
        keys: Sequence[str] | None = None,
    ) -> tuple[Any, Any]:
        """Plot a result of the metric (default: ``self.compute()``), or a list of them as curves over steps.

        Args:
            val: a result of ``compute()`` / ``forward()`` (a dict of statistics, or a number or one-element tensor
                for a scalar metric), a list of them (one per step), or ``None`` to plot ``self.compute()``.
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
        form, val = _forms(self.compute() if val is None else val)
        name = self._plot_name()
        if form == "result":
            flat = self._plot_result(val)
            chosen = self._chosen(flat, keys)
            return _bars(_result({k: flat[k] for k in chosen}, "val"), ax, chosen, name)
        if form == "results":
            steps = [self._plot_result(step) for step in val]
            chosen = self._chosen(steps[0], keys)
            for i, step in enumerate(steps[1:], start=1):
                if missing := [k for k in chosen if k not in step]:
                    raise KeyError(f"val[{i}]: {missing} not in this step's result, whose keys are {list(step)}")
            return _curves(
                [_result({k: s[k] for k in chosen}, f"val[{i}]") for i, s in enumerate(steps)], ax, name, None
            )
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
    fig, ax = plot_single_or_multi_val(
        val, ax=ax, higher_is_better=higher_is_better, lower_bound=lower, name=plain_label(name)
    )
    if fig is not None:  # a figure of ours: laid out when drawn, so a saved one keeps its labels and legend
        fig.set_layout_engine("constrained")
    return fig, ax


def _bars(result: dict[str, Tensor], ax: Any, chosen: list[str], name: str) -> tuple[Any, Any]:
    """One bar a statistic (colour: forward, reverse, symmetric), each labelled with its value."""
    import matplotlib.pyplot as plt

    values = [float(result[k]) for k in chosen]
    finite = [v if math.isfinite(v) else 0.0 for v in values]  # a NaN bar had no label at all, an inf one no height
    odd = [f"{k}={v:g}" for k, v in zip(chosen, values, strict=True) if not math.isfinite(v)]
    _warn_not_finite(name, odd, "each is a label over no bar")
    # constrained layout (as viz/plots.py's figures): a saved figure keeps its tilted names (they ran off its bottom)
    size = (max(4.0, 0.6 * len(chosen) + 1.5), 3.5)
    fig, ax = plt.subplots(figsize=size, layout="constrained") if ax is None else (None, ax)
    bars = ax.bar(range(len(chosen)), finite, color=[f"C{_direction(k)}" for k in chosen])
    ax.bar_label(bars, labels=[bar_label(k, v) for k, v in zip(chosen, values, strict=True)], fontsize=7)
    tilted = len(chosen) > 8
    ticks = [plain_label(k) for k in chosen]
    ax.set_xticks(range(len(chosen)), ticks, rotation=45 if tilted else 0, ha="right" if tilted else "center")
    ax.set_ylabel(plain_label(name))
    if min(finite) >= 0:
        ax.set_ylim(bottom=0.0)  # distances: the bars start at their lower bound
    ax.grid(True, axis="y")
    return fig, ax
