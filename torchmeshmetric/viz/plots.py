"""Matplotlib figures: histograms of the distance sets and per-frame curves over a sequence (PNG).

With the ``flicker`` set (always present in a sequence evaluation) the figures have six panels: the four sets of the
paper, ``flicker`` and the registration's residual (the noise floor of the ``k-1`` and flicker sets).
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from torchmeshmetric.evaluation.atomic import atomic_write
from torchmeshmetric.evaluation.results import SET_NAMES, PairEvaluation, SequenceEvaluation

__all__ = ["plot_frame_curves", "plot_histograms"]

_LABELS = {
    "surface_k_minus_1": "surface distance to registered k-1",
    "surface_k": "surface distance to k",
    "vertex_k_minus_1": "nearest vertex distance to registered k-1",
    "vertex_k": "nearest vertex distance to k",
    "flicker": "flicker: surface distance to simplified k-1 moved to k",
    "registration": "registration residual (noise floor of k-1 sets)",
}


def _panels(names: tuple[str, ...]) -> tuple[tuple[str, ...], tuple[int, int]]:
    """Panel keys and grid: the four sets (2 x 2), or with flicker also the registration residual (2 x 3)."""
    if len(names) > len(SET_NAMES):
        return (*names, "registration"), (2, 3)
    return names, (2, 2)


def _figure() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    return Figure


def _save(fig: Any, path: str | os.PathLike[str], overwrite: bool) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return atomic_write(path, buf.getvalue(), overwrite=overwrite)


def plot_histograms(
    methods: Mapping[str, PairEvaluation], path: str | os.PathLike[str], *, bins: int = 50, overwrite: bool = False
) -> Path:
    """Histograms of the distance sets of one frame pair, one colour per method, written as PNG.

    Args:
        methods: method name → its evaluation of the same frame pair.
        path: destination ``.png``.
        bins: number of bins (shared by the methods of a panel).
        overwrite: replace an existing file.
    """
    import numpy as np

    Figure = _figure()
    names, grid = _panels(min((p.set_names for p in methods.values()), key=len))
    fig = Figure(figsize=(5 * grid[1], 7), layout="constrained")
    axes = fig.subplots(*grid)
    for ax, name in zip(axes.ravel(), names, strict=True):
        sets = {m: p.registration_residual if name == "registration" else p.distances[name] for m, p in methods.items()}
        values = {m: d.detach().double().cpu().numpy() for m, d in sets.items()}
        hi = max(float(v.max()) for v in values.values()) or 1.0
        edges = np.linspace(0.0, hi, bins + 1)
        for m, v in values.items():
            ax.hist(v, bins=edges, alpha=0.55, label=f"{m} (RMSE {np.sqrt(np.mean(v * v)):.3g})")
        ax.set_title(_LABELS[name], fontsize=10)
        ax.set_xlabel("distance")
        ax.set_ylabel("vertices")
        ax.legend(fontsize=8)
    frame = next(iter(methods.values())).frame
    fig.suptitle(f"Distance sets of simplified frame {frame}")
    return _save(fig, path, overwrite)


def plot_frame_curves(
    methods: Mapping[str, SequenceEvaluation],
    path: str | os.PathLike[str],
    *,
    statistic: str = "rmse",
    overwrite: bool = False,
) -> Path:
    """Per-frame curves of one statistic of the distance sets over the sequence, one line per method, as PNG.

    Args:
        methods: method name → its sequence evaluation.
        path: destination ``.png``.
        statistic: a field of :class:`~torchmeshmetric.stats.DistanceStatistics` (default ``"rmse"``).
        overwrite: replace an existing file.
    """
    Figure = _figure()
    fig = Figure(figsize=(10, 7), layout="constrained")
    from matplotlib.ticker import MaxNLocator

    names, grid = _panels(min((seq.set_names for seq in methods.values()), key=len))
    fig.set_size_inches(5 * grid[1], 7)
    axes = fig.subplots(*grid, sharex=True)
    for ax, name in zip(axes.ravel(), names, strict=True):
        for m, seq in methods.items():
            frames = [p.frame for p in seq.pairs]
            stats = [p.registration_statistics if name == "registration" else p.statistics[name] for p in seq.pairs]
            ax.plot(frames, [float(getattr(st, statistic)) for st in stats], marker="o", label=m)
        ax.set_title(_LABELS[name], fontsize=10)
        ax.set_xlabel("frame k (pair k-1, k)")
        ax.set_ylabel(statistic.upper() if statistic in ("mse", "rmse") else statistic)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # frames are integers
        ax.legend(fontsize=8)
    fig.suptitle(f"{statistic.upper() if statistic in ('mse', 'rmse') else statistic} per frame pair")
    return _save(fig, path, overwrite)
