"""The Registered QEM weight sweep as a Pareto plot: frame-k error against k-1 error and flicker (PNG)."""

from __future__ import annotations

import os
from pathlib import Path

from torchmeshmetric._checks import check_flag
from torchmeshmetric.evaluation.sweep import WeightSweep, pareto_front
from torchmeshmetric.viz.plots import _figure, _save

__all__ = ["plot_weight_sweep"]


def plot_weight_sweep(
    sweep: WeightSweep, path: str | os.PathLike[str], *, statistic: str = "ave", overwrite: bool = False
) -> Path:
    """Two panels: frame-k error (x) against the registered k-1 error and against flicker (y), one point per weight.

    The weights are joined in order and labelled; the points on the Pareto front (no other weight lower in both
    coordinates) are filled; plain QEM (the sweep's baseline) is a separate marker.

    Args:
        sweep: a :class:`~torchmeshmetric.evaluation.sweep.WeightSweep`.
        path: destination ``.png``.
        statistic: the statistic plotted (mean over pairs; default ``"ave"``).
        overwrite: replace an existing file.

    Returns:
        The path written.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        KeyError: ``statistic`` is not a statistic of the sets.
        TypeError: ``overwrite`` is not a bool.

    Example:
        >>> import os, tempfile, trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 2
        >>> moved = [f.copy().apply_translation([0.01, 0, 0]) for f in frames]
        >>> seq = evaluate_sequence(frames, moved, registration_fn=lambda s, t: s)
        >>> from torchmeshmetric.evaluation import WeightSweep
        >>> sweep = WeightSweep(weights=[0.5], results=[seq], baseline=seq)  # as registered_qem_sweep returns it
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     png = plot_weight_sweep(sweep, os.path.join(folder, "sweep.png")).read_bytes()
        >>> png[1:4]  # the PNG signature
        b'PNG'
    """
    overwrite = check_flag(overwrite, "overwrite")
    Figure = _figure()
    fig = Figure(figsize=(11, 4.8), layout="constrained")
    axes = fig.subplots(1, 2)
    rows = sweep.rows(statistic)
    swept = [r for r in rows if r["weight"] is not None]
    base = [r for r in rows if r["weight"] is None]
    for ax, y_set, label in zip(
        axes, ("surface_k_minus_1", "flicker"), ("surface distance to registered k-1", "flicker"), strict=True
    ):
        xs = [r["surface_k"] for r in swept]
        ys = [r[y_set] for r in swept]
        front = set(pareto_front({r["weight"]: (r["surface_k"], r[y_set]) for r in swept}))
        ax.plot(xs, ys, "-", color="tab:blue", alpha=0.5)
        for r, x, y in zip(swept, xs, ys, strict=True):
            filled = r["weight"] in front
            ax.plot(x, y, "o", color="tab:blue", markerfacecolor="tab:blue" if filled else "white")
            ax.annotate(f"w={r['weight']:g}", (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
        for r in base:
            ax.plot(r["surface_k"], r[y_set], "s", color="tab:red", label="QEM (fast-simplification)")
        ax.plot([], [], "o", color="tab:blue", label="Registered QEM (filled: Pareto front)")
        xs_all = xs + [r["surface_k"] for r in base]
        if min(xs_all) > 0 and max(xs_all) / min(xs_all) > 10:
            from matplotlib.ticker import NullFormatter  # matplotlib on use only (see plots._figure)

            ax.set_xscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())  # minor labels overlap on a short log range
        ax.set_xlabel(f"frame k error: surface distance to k ({statistic}, mean over pairs)")
        ax.set_ylabel(f"{label} ({statistic})")
        ax.legend(fontsize=8)
    fig.suptitle("Registered QEM weight sweep (lower is better on both axes)")
    return _save(fig, path, overwrite)
