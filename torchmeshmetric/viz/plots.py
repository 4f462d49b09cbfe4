"""Matplotlib figures: histograms of the four distance sets and per-frame curves over a sequence (PNG)."""

from __future__ import annotations

import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from torchmeshmetric._atomic import atomic_write
from torchmeshmetric._checks import check_flag
from torchmeshmetric._format import plain_label
from torchmeshmetric.evaluation.flicker import FLICKER
from torchmeshmetric.evaluation.reports import statistic_cell
from torchmeshmetric.evaluation.results import SET_NAMES, PairEvaluation, SequenceEvaluation

__all__ = [
    "frame_curves_figure",
    "histogram_figure",
    "log_bins",
    "mpeg_figure",
    "plot_frame_curves",
    "plot_histograms",
    "plot_mpeg_curves",
    "png_bytes",
]

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
    """The ``Figure`` class on the Agg backend; imported on first use: no module of the package imports matplotlib."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    return Figure


def png_bytes(fig: Any) -> bytes:
    """A figure as the PNG bytes every plot of the package is written as (110 dpi)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def _save(fig: Any, path: str | os.PathLike[str], overwrite: bool) -> Path:
    return atomic_write(path, png_bytes(fig), overwrite=overwrite)


def log_bins(values: Sequence[Any], bins: int, *, decades: float = 6.0) -> Any:
    """Log-spaced bin edges for distance sets whose mass sits at (or near) zero.

    Most vertices of a good simplification lie on the reference surface, so linear bins put nearly everything in the
    first bar. The edges span ``[lo, hi]`` with ``hi`` the largest distance and ``lo`` the smallest positive one,
    but at most ``decades`` decades below ``hi``; values below ``lo`` (zeros included) are left to the caller
    (:func:`histogram_figure` gives their fraction in the legend).

    Args:
        values: the distance arrays sharing the edges (one per method).
        bins: number of bins.
        decades: widest span of the axis, in powers of ten.

    Returns:
        ``(bins + 1,)`` increasing edges (a unit range when every distance is zero; the decade below the largest
        distance when all positive ones are equal to within a millionth).

    Example:
        >>> import numpy as np
        >>> log_bins([np.array([0.0, 0.0, 1e-3, 1e-2, 1e-1])], 2).round(6).tolist()
        [0.001, 0.01, 0.1]
    """
    hi = max((float(np.max(v)) for v in values if len(v)), default=0.0)
    positive = [np.min(v[v > 0]) for v in values if np.any(v > 0)]
    if hi <= 0 or not positive:
        return np.geomspace(1e-6, 1.0, bins + 1)
    lo = max(float(min(positive)), hi * 10.0**-decades)
    if lo >= hi * (1.0 - 1e-6):
        # Equal distances, or equal but for rounding (a translation's nearest-vertex distances: 0.1 and one ulp
        # below): no spread to show, and edges one ulp apart made the axis' limits identical. A decade below.
        lo = hi / 10.0
    return np.geomspace(lo, hi, bins + 1)


def histogram_figure(methods: Mapping[str, PairEvaluation], *, bins: int = 50) -> Any:
    """The figure of :func:`plot_histograms` (a ``matplotlib.figure.Figure``): log-scaled distances, one panel a set.

    Bars count the vertices at or above the axis' lowest edge; the legend gives each method's RMSE and the fraction
    of its vertices below that edge (on the surface, distance 0, or within ``1e-6`` of the largest distance).
    """
    Figure = _figure()
    names, grid = _panels(min((p.set_names for p in methods.values()), key=len))
    fig = Figure(figsize=(5 * grid[1], 7), layout="constrained")
    axes = fig.subplots(*grid)
    for ax, name in zip(axes.ravel(), names, strict=True):
        sets = {m: p.registration_residual if name == "registration" else p.distances[name] for m, p in methods.items()}
        values = {m: d.detach().double().cpu().numpy() for m, d in sets.items()}
        edges = log_bins(list(values.values()), bins)
        for m, v in values.items():
            below = float(np.mean(v < edges[0])) if len(v) else 0.0
            rmse = statistic_cell(float(np.sqrt(np.mean(v * v))), "rmse")  # the tables' determined digits
            label = f"{plain_label(m)} (RMSE {rmse}; {below:.1%} of vertices below {edges[0]:.2g})"
            ax.hist(v[v >= edges[0]], bins=edges, alpha=0.55, label=label)
        # The axis spans the bins even when no bar is drawn (every distance below the lowest edge, e.g. an exact
        # registration's residual): matplotlib's default limits of an empty panel are not valid on a log scale.
        ax.set_xlim(edges[0], edges[-1])
        ax.set_xscale("log")
        ax.set_title(_LABELS[name], fontsize=10)
        ax.set_xlabel("distance (log scale)")
        ax.set_ylabel("vertices")
        ax.legend(fontsize=8)
    frame = next(iter(methods.values())).frame
    fig.suptitle(f"Distance sets of simplified frame {frame}")
    return fig


def plot_histograms(
    methods: Mapping[str, PairEvaluation], path: str | os.PathLike[str], *, bins: int = 50, overwrite: bool = False
) -> Path:
    """Histograms of the distance sets of one frame pair, one colour per method, written as PNG.

    The distance axis is logarithmic (:func:`log_bins`): most kept vertices lie on the reference surface, and on a
    linear axis the whole distribution is one bar at zero.

    Args:
        methods: method name → its evaluation of the same frame pair.
        path: destination ``.png``.
        bins: number of bins (shared by the methods of a panel).
        overwrite: replace an existing file.

    Returns:
        The path written (a PNG of :func:`histogram_figure`).

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        TypeError: ``overwrite`` is not a bool.

    Example:
        >>> import os, tempfile, trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 2
        >>> moved = [f.copy().apply_translation([0.01, 0, 0]) for f in frames]
        >>> seq = evaluate_sequence(frames, moved, registration_fn=lambda s, t: s)
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     png = plot_histograms({"moved": seq.pairs[0]}, os.path.join(folder, "hist.png")).read_bytes()
        >>> png[1:4]  # the PNG signature
        b'PNG'
    """
    overwrite = check_flag(overwrite, "overwrite")
    return _save(histogram_figure(methods, bins=bins), path, overwrite)


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

    Returns:
        The path written (a PNG of :func:`frame_curves_figure`).

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
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     png = plot_frame_curves({"moved": seq}, os.path.join(folder, "rmse.png")).read_bytes()
        >>> png[1:4]  # the PNG signature
        b'PNG'
    """
    overwrite = check_flag(overwrite, "overwrite")
    pairs = {m: [p.as_dict() for p in seq.pairs] for m, seq in methods.items()}
    return _save(frame_curves_figure(pairs, statistic=statistic), path, overwrite)


def frame_curves_figure(pairs: Mapping[str, Sequence[Mapping[str, Any]]], *, statistic: str = "rmse") -> Any:
    """The figure of :func:`plot_frame_curves`, from the pairs as a report holds them.

    Args:
        pairs: method name → its pairs in frame order, each as :meth:`PairEvaluation.as_dict` writes it (the
            ``"pairs"`` of a method in ``report.json``).
        statistic: a statistic of the sets (default ``"rmse"``).

    Returns:
        A ``matplotlib.figure.Figure``: one panel a set (and the registration's residual when flicker is measured).
    """
    Figure = _figure()
    from matplotlib.ticker import MaxNLocator  # matplotlib on use only (see _figure)

    measured = [tuple(n for n in (*SET_NAMES, FLICKER) if all(n in p for p in ps)) for ps in pairs.values()]
    names, grid = _panels(min(measured, key=len))
    fig = Figure(figsize=(5 * grid[1], 7), layout="constrained")
    axes = fig.subplots(*grid, sharex=True)
    label = statistic.upper() if statistic in ("mse", "rmse") else statistic
    for ax, name in zip(axes.ravel(), names, strict=True):
        for m, ps in pairs.items():
            stats = [p["registration"]["residual"] if name == "registration" else p[name] for p in ps]
            ax.plot([p["frame"] for p in ps], [float(st[statistic]) for st in stats], marker="o", label=plain_label(m))
        ax.set_title(_LABELS[name], fontsize=10)
        ax.set_xlabel("frame k (pair k-1, k)")
        ax.set_ylabel(label)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # frames are integers
        ax.legend(fontsize=8)
    fig.suptitle(f"{label} per frame pair")
    return fig


def plot_mpeg_curves(methods: Mapping[str, Any], path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
    """Per-frame MPEG D1 and D2 PSNR (and Luma PSNR when present), one line per method, as PNG.

    Args:
        methods: method name → its :class:`~torchmeshmetric.mpeg.comparison.sequence.MpegSequence`.
        path: destination ``.png``.
        overwrite: replace an existing file.

    Returns:
        The path written: one panel per figure (``d1_psnr``, ``d2_psnr``, and ``y_psnr`` when every frame has it);
        an infinite PSNR (identical frames) is a gap in its line.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        TypeError: ``overwrite`` is not a bool.

    Example:
        >>> import os, tempfile, trimesh
        >>> from torchmeshmetric.mpeg import mpeg_sequence
        >>> a = trimesh.creation.icosphere(1)
        >>> seq = mpeg_sequence([a, a], [a, a.copy().apply_scale(1.01)], sampling="mesh")
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     png = plot_mpeg_curves({"scaled": seq}, os.path.join(folder, "mpeg.png")).read_bytes()
        >>> png[1:4]  # the PNG signature
        b'PNG'
    """
    overwrite = check_flag(overwrite, "overwrite")
    return _save(mpeg_figure(methods), path, overwrite)


def mpeg_figure(methods: Mapping[str, Any]) -> Any:
    """The figure of :func:`plot_mpeg_curves` (a ``matplotlib.figure.Figure``)."""
    Figure = _figure()
    from matplotlib.ticker import MaxNLocator  # matplotlib on use only (see _figure)

    rows = {m: seq.frame_rows() for m, seq in methods.items()}
    keys = ["d1_psnr", "d2_psnr"] + (["y_psnr"] if all("y_psnr" in r for rs in rows.values() for r in rs) else [])
    fig = Figure(figsize=(5 * len(keys), 4), layout="constrained")
    axes = fig.subplots(1, len(keys), squeeze=False)[0]
    for ax, key in zip(axes, keys, strict=True):
        for m, rs in rows.items():
            # an identical frame has an infinite PSNR: drawn as a gap, counted in the report's *_inf_frames
            ax.plot(
                [r["frame"] for r in rs],
                [r[key] if r[key] != float("inf") else float("nan") for r in rs],
                marker="o",
                label=plain_label(m),
            )
        ax.set_title(key.replace("_", " ").upper().replace("PSNR", "PSNR (dB)"), fontsize=10)
        ax.set_xlabel("frame")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.legend(fontsize=8)
    fig.suptitle("MPEG (mmetric) PSNR per frame")
    return fig
