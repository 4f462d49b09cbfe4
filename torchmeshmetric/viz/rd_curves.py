"""Rate-distortion curves of a CTC campaign: anchor and test codec, one panel per metric (PNG)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from torchmeshmetric._checks import check_flag
from torchmeshmetric._format import plain_label
from torchmeshmetric.viz.plots import _figure, _save

__all__ = ["plot_rd_curves"]

_METRICS = ("GridD1", "GridD2", "GridLuma", "GridChromaCb", "GridChromaCr", "IbsmGeom", "IbsmLuma")


def plot_rd_curves(
    sequence: Mapping[str, Any],
    path: str | os.PathLike[str],
    *,
    names: tuple[str, str] = ("anchor", "test"),
    title: str = "",
    overwrite: bool = False,
) -> Path:
    """One sequence's RD curves: rate (Mbps) against each metric's PSNR, anchor and test codec, as a PNG.

    Args:
        sequence: a sequence of :func:`~torchmeshmetric.mpeg.ctc.sheet.ctc_summary` (its ``rates`` rows, and its
            ``bd_rate`` figures, shown in each panel's title).
        path: destination ``.png``.
        names: the two codecs' names (legend).
        title: the figure's title.
        overwrite: replace an existing file.

    Returns:
        The path written.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        TypeError: ``overwrite`` is not a bool.

    Example:
        >>> import os, tempfile
        >>> rows = [{"anchor": {"rate_mbps": r, "GridD1": 60 + r}, "test": {"rate_mbps": 0.9 * r, "GridD1": 60 + r}}
        ...         for r in (1.0, 2.0, 4.0)]
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     path = plot_rd_curves({"rates": rows}, os.path.join(folder, "rd.png"))
        ...     path.name, path.read_bytes()[1:4]  # the PNG signature
        ('rd.png', b'PNG')
    """
    overwrite = check_flag(overwrite, "overwrite")
    Figure = _figure()
    rows = sequence["rates"]
    metrics = [m for m in _METRICS if all(m in r["anchor"] and m in r["test"] for r in rows)]
    cols = min(4, max(1, len(metrics)))
    nrows = max(1, -(-len(metrics) // cols))
    fig = Figure(figsize=(4 * cols, 3.4 * nrows))  # fixed margins: a constrained layout costs seconds per figure
    axes = fig.subplots(nrows, cols, squeeze=False).ravel()
    for ax, m in zip(axes, metrics, strict=False):
        for side, label, marker in (("anchor", names[0], "o"), ("test", names[1], "s")):
            pts = sorted((r[side]["rate_mbps"], r[side][m]) for r in rows)
            ax.plot([x for x, _ in pts], [y for _, y in pts], marker=marker, label=plain_label(label))
        bd = sequence.get("bd_rate", {}).get(m)
        ax.set_title(m + ("" if bd is None else f"  (BD-rate {bd:+.2f} %)"), fontsize=9)
        ax.set_xlabel("rate (Mbps)")
        ax.set_ylabel("PSNR (dB)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes[len(metrics) :]:
        ax.set_visible(False)
    if title:
        fig.suptitle(plain_label(title))
    h, w = 3.4 * nrows, 4.0 * cols  # margins in inches: 0.55 below, 0.65 above, 0.7 left
    fig.subplots_adjust(left=0.7 / w, right=1 - 0.15 / w, bottom=0.55 / h, top=1 - 0.65 / h, wspace=0.35, hspace=0.5)
    return _save(fig, path, overwrite)
