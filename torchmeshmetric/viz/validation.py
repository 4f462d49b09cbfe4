"""The validation study's curves: each set's statistic against the injected strength, one panel per distortion."""

from __future__ import annotations

import math
import os
from pathlib import Path

from torchmeshmetric._checks import check_flag
from torchmeshmetric.evaluation.validation import ValidationResult
from torchmeshmetric.viz.plots import _figure, _save

__all__ = ["plot_validation"]

_SETS = ("surface_k", "surface_k_minus_1", "vertex_k", "vertex_k_minus_1", "flicker", "reverse:surface_k")


def plot_validation(
    result: ValidationResult, path: str | os.PathLike[str], *, statistic: str = "ave", overwrite: bool = False
) -> Path:
    """One panel per distortion: ``statistic`` of each set (mean over pairs) against the strength, as PNG.

    Values are drawn relative to the set's value at strength 0 (1 = unchanged); a set that starts at 0 (the
    one-sided frame-k sets of a simplification whose vertices lie on the surface) is drawn against the diagonal
    instead, as ``1 + value / (1e-3 diagonal)``, and marked ``(from 0)``.

    Args:
        result: the study's result (:func:`~torchmeshmetric.evaluation.validation.run_validation`); its
            ``settings["diagonal"]`` scales the sets that start at 0.
        path: destination ``.png``.
        statistic: the statistic plotted (mean over pairs; default ``"ave"``).
        overwrite: replace an existing file.

    Returns:
        The path written: up to 4 panels a row.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        KeyError: ``statistic`` is not among the study's statistics.
        TypeError: ``overwrite`` is not a bool.

    Example:
        >>> import os, tempfile
        >>> from torchmeshmetric.evaluation.validation import ValidationResult
        >>> noise = {"strengths": [0.0, 0.1], "values": {"surface_k": {"ave": [0.01, 0.02]}}}
        >>> result = ValidationResult({"diagonal": 2.0}, {"noise": noise}, registration={}, seconds=0.0)
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     png = plot_validation(result, os.path.join(folder, "validation.png")).read_bytes()
        >>> png[1:4]  # the PNG signature
        b'PNG'
    """
    overwrite = check_flag(overwrite, "overwrite")
    Figure = _figure()
    names = list(result.distortions)
    cols = min(4, len(names))
    rows = math.ceil(len(names) / cols)
    fig = Figure(figsize=(4.2 * cols, 3.6 * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    scale = 1e-3 * float(result.settings["diagonal"])
    for ax, name in zip(axes, names, strict=False):
        d = result.distortions[name]
        for set_name in _SETS:
            if set_name not in d["values"]:
                continue
            v = d["values"][set_name][statistic]
            from_zero = abs(v[0]) <= 1e-9 * float(result.settings["diagonal"])
            y = [1 + x / scale for x in v] if from_zero else [x / v[0] for x in v]
            ax.plot(d["strengths"], y, marker="o", label=set_name + (" (from 0)" if from_zero else ""))
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("strength")
        ax.set_ylabel(f"{statistic} / {statistic} at 0")
        ax.legend(fontsize=6)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    fig.suptitle(f"Validation: {statistic} of each set against the injected strength")
    return _save(fig, path, overwrite)
