"""MPEG figures over a sequence: per-frame D1/D2 (and colour) PSNR and Hausdorff, averaged as the CTC does.

Averaging rule: the sequence figure of a PSNR is the **mean of the per-frame PSNR values** (the V-DMC CTC and
mmetric's multi-frame summary average PSNR, not MSE). A frame identical to its reference has an infinite PSNR
(mmetric prints ``inf``); mmetric has no clipping rule, so its own mean would become ``inf`` and hide every other
frame. Here the mean is taken over the frames with a finite PSNR and the number of infinite frames is reported
beside it (``<key>_inf_frames``); when every frame is infinite the mean is ``inf``. MSE and Hausdorff are averaged
over all frames. In JSON, infinities are written as the string ``"inf"``.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from torchmeshmetric._format import markdown_cell
from torchmeshmetric.mpeg.comparison.mpeg_metrics import BoxLike, Sampling, mpeg_metrics
from torchmeshmetric.mpeg.comparison.pcc import MpegResult
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.stats.statistics import mean_psnr  # the one rule, Tables III/IV's too
from torchmeshmetric.structures import MeshLike

__all__ = ["AVERAGING_RULE", "FRAME_KEYS", "MpegSequence", "mean_psnr", "mpeg_sequence"]

AVERAGING_RULE = (
    "mean over frames of the per-frame PSNR (CTC); frames with infinite PSNR (identical to the reference) are "
    "left out of the mean and counted in <key>_inf_frames; mean = inf only when every frame is infinite"
)
FRAME_KEYS = (
    "d1_psnr",
    "d2_psnr",
    "d1_mse",
    "d2_mse",
    "d1_hausdorff",
    "d2_hausdorff",
    "d1_hausdorff_psnr",
    "d2_hausdorff_psnr",
    "y_psnr",
    "cb_psnr",
    "cr_psnr",
)


@dataclass(frozen=True)
class MpegSequence:
    """Per-frame MPEG results of one method and their sequence averages.

    Attributes:
        frames: frame numbers (position in the sequence).
        results: the :class:`MpegResult` of each frame (symmetric figures used below).
        sampling: ``"grid"`` or ``"mesh"``.

    Example:
        >>> import trimesh
        >>> a = trimesh.creation.icosphere(1)
        >>> s = mpeg_sequence([a, a], [a, a.copy().apply_scale(1.01)], sampling="mesh")
        >>> s.frames, s.sampling, s.results[0].symmetric.d1_psnr  # frame 0 identical: inf
        ([0, 1], 'mesh', inf)
    """

    frames: list[int]
    results: list[MpegResult]
    sampling: str

    def frame_rows(self) -> list[dict[str, float]]:
        """One dict per frame with :data:`FRAME_KEYS` (colour keys only when both meshes carry colour)."""
        rows = []
        for k, r in zip(self.frames, self.results, strict=True):
            d = r.to_dict()
            row: dict[str, float] = {"frame": float(k)}
            row.update({key: float(d[key]) for key in FRAME_KEYS if key in d})  # type: ignore[arg-type]
            rows.append(row)
        return rows

    def average(self) -> dict[str, float]:
        """Sequence figures: CTC mean of PSNR (finite frames) with ``*_inf_frames`` counts, mean of MSE/Hausdorff."""
        rows = self.frame_rows()
        out: dict[str, float] = {}
        for key in FRAME_KEYS:
            vals = [row[key] for row in rows if key in row]
            if not vals:
                continue
            if key.endswith("psnr"):
                mean, inf_frames = mean_psnr(vals, f"the frames' {key}")
                out[key], out[f"{key}_inf_frames"] = mean, float(inf_frames)
            else:
                out[key] = sum(vals) / len(vals)
        return out

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: ``{"sampling", "averaging", "frames": [...], "average": {...}}``."""
        return {
            "sampling": self.sampling,
            "averaging": AVERAGING_RULE,
            "frames": self.frame_rows(),
            "average": self.average(),
        }


def mpeg_sequence(
    reference: Sequence[MeshLike | TexturedMesh],
    distorted: Sequence[MeshLike | TexturedMesh],
    *,
    sampling: Sampling = "grid",
    grid_size: int = 1024,
    box: BoxLike | None = None,
    progress: Callable[[int, int], None] | None = None,
    names: tuple[str, str] = ("reference", "distorted"),
) -> MpegSequence:
    """MPEG figures of every frame (distorted frame k against reference frame k), as the CTC reports a sequence.

    Args:
        reference: reference frames.
        distorted: distorted (decoded, simplified) frames, same count.
        sampling: ``"grid"`` (CTC) or ``"mesh"``.
        grid_size: grid steps (grid mode).
        box: one sampling box for every frame; default each reference frame's own box (as the CTC runs mmetric per
            frame).
        progress: called with ``(done, total)`` after each frame.
        names: how error messages name the two sequences (a frame is ``"<name> frame <k>"``).

    Returns:
        :class:`MpegSequence`.

    Raises:
        ValueError: the frame counts differ or are zero.

    Example:
        >>> import trimesh
        >>> a = trimesh.creation.icosphere(1)
        >>> b = a.copy().apply_scale(1.01)
        >>> s = mpeg_sequence([a, a], [a, b], sampling="mesh")
        >>> s.average()["d1_psnr_inf_frames"], s.average()["d1_psnr"] > 30
        (1.0, True)
    """
    if len(reference) != len(distorted) or len(reference) == 0:
        raise ValueError(
            f"distorted: expected as many frames as the reference ({len(reference)}, at least 1), found "
            f"{len(distorted)}"
        )
    results = []
    for k, (r, d) in enumerate(zip(reference, distorted, strict=True)):
        frame_names = (f"{names[0]} frame {k}", f"{names[1]} frame {k}")
        results.append(mpeg_metrics(r, d, sampling=sampling, grid_size=grid_size, box=box, names=frame_names))
        if progress is not None:
            progress(k + 1, len(reference))
    return MpegSequence(list(range(len(reference))), results, sampling)


def _fmt(x: float) -> str:
    return "inf" if math.isinf(x) else ("nan" if math.isnan(x) else f"{x:.4f}")


def mpeg_markdown(methods: Mapping[str, MpegSequence]) -> str:
    """Markdown section: per-frame D1/D2 (and colour) PSNR and Hausdorff PSNR per method, with the CTC average.

    Example:
        >>> import trimesh
        >>> a = trimesh.creation.icosphere(1)
        >>> print(mpeg_markdown({"m": mpeg_sequence([a], [a], sampling="mesh")}).splitlines()[0])
        ## MPEG D1/D2 (mmetric, mesh sampling)
    """
    sampling = next(iter(methods.values())).sampling if methods else "grid"
    out = [f"## MPEG D1/D2 (mmetric, {sampling} sampling)", ""]
    keys = ["d1_psnr", "d2_psnr", "d1_hausdorff_psnr", "d2_hausdorff_psnr"]
    if methods and all("y_psnr" in row for s in methods.values() for row in s.frame_rows()):
        keys += ["y_psnr", "cb_psnr", "cr_psnr"]
    out.append("| algorithm | frame | " + " | ".join(keys) + " |")
    out.append("|---|---|" + "---|" * len(keys))
    for name, seq in methods.items():
        for row in seq.frame_rows():
            out.append(
                f"| {markdown_cell(name)} | {int(row['frame'])} | "
                + " | ".join(_fmt(row.get(k, math.nan)) for k in keys)
                + " |"
            )
        avg = seq.average()
        out.append(f"| {markdown_cell(name)} | mean | " + " | ".join(_fmt(avg.get(k, math.nan)) for k in keys) + " |")
    out += ["", f"Averages: {AVERAGING_RULE}.", ""]
    return "\n".join(out)


def mpeg_csv(methods: Mapping[str, MpegSequence]) -> str:
    """CSV: ``algorithm, frame, <FRAME_KEYS>``; one row per frame and a ``mean`` row per method (CTC rule).

    Example:
        >>> import trimesh
        >>> a = trimesh.creation.icosphere(1)
        >>> header = mpeg_csv({"m": mpeg_sequence([a], [a], sampling="mesh")}).splitlines()[0]
        >>> header.startswith("algorithm,frame,d1_psnr,d2_psnr")
        True
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["algorithm", "frame", *FRAME_KEYS])
    for name, seq in methods.items():
        for row in seq.frame_rows():
            w.writerow([name, int(row["frame"]), *(repr(row[k]) if k in row else "" for k in FRAME_KEYS)])
        avg = seq.average()
        w.writerow([name, "mean", *(repr(avg[k]) if k in avg else "" for k in FRAME_KEYS)])
    return buf.getvalue()
