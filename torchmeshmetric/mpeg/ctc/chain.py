"""The V-DMC CTC metric step: mmetric's ``sequence`` chain of dequantise, grid sampling and comparison, per frame.

The MPEG V-DMC test model (``scripts/run.sh``, mmetric v1.1.7) runs, for every frame of a sequence:

1. ``dequantize --useFixedPoint --qp QP --qt QT --minPos MIN --maxPos MAX --minUv "0 0" --maxUv "1 1"`` on the
   source frame and on the decoded frame (:mod:`torchmeshmetric.mpeg.ctc.dequantize`);
2. ``reindex --sort oriented`` on both (corners merged and sorted, each face rotated to start at its smallest
   corner, duplicate faces dropped: the float32 ray-triangle arithmetic of the sampling depends on that order);
3. ``sample --mode grid --gridSize 1024 --useNormal --useFixedPoint --bilinear --minPos MIN --maxPos MAX`` on both
   (the *sequence's* box, rounded to 1/65536, for every frame; a decoded frame may reach outside it);
4. ``compare --mode pcc --resolution R``, R = the longest side of the sequence's box;
5. ``compare --mode ibsm`` on the two dequantised meshes with their textures (2048 x 2048 buffers, 16 cameras,
   software renderer, culling and reordering on: :func:`~torchmeshmetric.mpeg.comparison.ibsm.ibsm`).

The figures are the CTC spreadsheet's ``GridD1`` (D1 PSNR), ``GridD2`` (D2 PSNR), ``GridLuma``, ``GridChromaCb``,
``GridChromaCr`` (colour PSNR, when both frames carry a texture or vertex colours), ``IbsmGeom`` (IBSM's GEO
PSNR) and ``IbsmLuma`` (its Y PSNR), and the sequence figure of each
is mmetric's statistic: the arithmetic mean over frames of the per-frame PSNR clipped at 99.99.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from torchmeshmetric._checks import check_positive_real
from torchmeshmetric.mpeg.comparison.ibsm import IbsmResult, ibsm
from torchmeshmetric.mpeg.comparison.pcc import mpeg_compare
from torchmeshmetric.mpeg.core.point_cloud import PointCloud
from torchmeshmetric.mpeg.core.reindex import oriented_reindex
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.mpeg.ctc.dequantize import dequantize_positions, dequantize_uvs
from torchmeshmetric.mpeg.ctc.settings import Corner, CtcKeywords, CtcSettings, resolve_settings
from torchmeshmetric.mpeg.sampling.grid_sampling import grid_sample
from torchmeshmetric.structures import Mesh

if TYPE_CHECKING:  # typing.Unpack needs Python 3.11; annotations are not evaluated at run time
    from typing_extensions import Unpack

__all__ = [
    "CTC_CLIP",
    "CTC_COLUMNS",
    "CtcFrame",
    "CtcSequence",
    "ctc_frame",
    "ctc_mean",
    "ctc_sequence",
]

CTC_COLUMNS = ("GridD1", "GridD2", "GridLuma", "GridChromaCb", "GridChromaCr", "IbsmGeom", "IbsmLuma")
"""The CTC spreadsheet's metric columns, in its order."""

CTC_CLIP = 99.99
"""mmetric's statistics clip every per-frame PSNR at this value before averaging (``mm::CLIP``)."""


def ctc_mean(values: Sequence[float], clip: float = CTC_CLIP) -> float:
    """The sequence mean of mmetric: ``sum_i (1/n) * min(psnr_i, clip)``, accumulated in that order in float64.

    An infinite PSNR (a frame identical to its source) counts as ``clip``; NaN stays NaN.

    Args:
        values: the per-frame PSNRs in dB.
        clip: the ceiling an infinite PSNR counts as, a finite number > 0 (mmetric's 99.99 dB).

    Returns:
        The mean in dB.

    Raises:
        ValueError: no value (a mean of nothing is no figure), or ``clip`` not a finite positive number (``-1`` was
            taken: every frame then counted as -1 dB).

    Example:
        >>> ctc_mean([40.0, float("inf")])
        69.995
    """
    clip = check_positive_real(clip, "clip")
    if len(values) == 0:
        raise ValueError("values: expected at least one per-frame PSNR, found none")
    fract = 1.0 / len(values)
    mean = 0.0
    for v in values:
        mean += fract * min(float(v), clip) if not math.isnan(v) else math.nan
    return mean


@dataclass(frozen=True)
class CtcFrame:
    """The CTC figures of one frame (keys of :data:`CTC_COLUMNS`; a figure not computed is absent).

    Attributes:
        frame: the frame number.
        figures: column name -> PSNR in dB (unclipped, ``inf`` for identical frames).
        points_ref: the reference's grid samples after duplicate merging.
        points_dis: the decoded frame's.
        seconds: wall seconds per stage (``dequantize``, ``grid``, ``pcc``, ``ibsm``; IBSM runs beside the grid and pcc
            stages, so the stages may add up to more than the frame took).

    Example:
        >>> import numpy as np, torch, trimesh
        >>> from torchmeshmetric import Mesh
        >>> from torchmeshmetric.mpeg import TexturedMesh
        >>> s = trimesh.creation.icosphere(2)
        >>> q = TexturedMesh(Mesh(torch.tensor(np.round((s.vertices + 1) * 511.5)), torch.tensor(s.faces)))  # 10 bits
        >>> f = ctc_frame(q, q, qp=10, qt=0, min_pos=[-1] * 3, max_pos=[1] * 3, grid_size=64, ibsm_resolution=None,
        ...               frame=3)
        >>> f.frame, f.figures, f.points_ref == f.points_dis, sorted(f.seconds)
        (3, {'GridD1': inf, 'GridD2': inf}, True, ['dequantize', 'grid', 'ibsm', 'pcc'])
    """

    frame: int
    figures: dict[str, float]
    points_ref: int = 0
    points_dis: int = 0
    seconds: dict[str, float] = field(default_factory=dict, compare=False)


@dataclass(frozen=True)
class CtcSequence:
    """Per-frame CTC figures of one decoded sequence and their means (mmetric's statistics).

    Attributes:
        frames: one :class:`CtcFrame` per frame, in order.
        columns: the figures present, in spreadsheet order.

    Example:
        >>> import numpy as np, torch, trimesh
        >>> from torchmeshmetric import Mesh
        >>> from torchmeshmetric.mpeg import TexturedMesh
        >>> s = trimesh.creation.icosphere(2)
        >>> q = TexturedMesh(Mesh(torch.tensor(np.round((s.vertices + 1) * 511.5)), torch.tensor(s.faces)))  # 10 bits
        >>> seq = ctc_sequence([(0, q, q), (1, q, q)], qp=10, qt=0, min_pos=[-1] * 3, max_pos=[1] * 3, grid_size=64,
        ...                    ibsm_resolution=None)
        >>> [f.frame for f in seq.frames], seq.columns, seq.mean()  # mmetric's mean clips inf to 99.99
        ([0, 1], ('GridD1', 'GridD2'), {'GridD1': 99.99, 'GridD2': 99.99})
    """

    frames: list[CtcFrame]
    columns: tuple[str, ...] = field(default=CTC_COLUMNS)

    def mean(self) -> dict[str, float]:
        """Column -> :func:`ctc_mean` over the frames that have it."""
        out = {}
        for c in self.columns:
            vals = [f.figures[c] for f in self.frames if c in f.figures]
            if vals:
                out[c] = ctc_mean(vals)
        return out

    def as_dict(self) -> dict[str, Any]:
        """``{"frames": [{"frame": i, "GridD1": ...}, ...], "mean": {...}}`` (floats may be infinite)."""
        rows = [{"frame": f.frame, **{c: f.figures[c] for c in self.columns if c in f.figures}} for f in self.frames]
        return {"frames": rows, "mean": self.mean()}


def _dequantized(mesh: TexturedMesh, qp: int, qt: int, box: tuple[Corner, Corner], name: str,
                 qt_name: str) -> TexturedMesh:  # fmt: skip
    """The dequantised mesh; an error names the argument (``ref`` / ``dis``, ``qt`` / ``decoded_qt``)."""
    if not isinstance(mesh, TexturedMesh):
        raise TypeError(f"{name}: expected a TexturedMesh (load_textured_mesh), found {type(mesh).__name__}")
    try:
        verts = dequantize_positions(mesh.mesh.verts, qp, box[0], box[1], fixed_point=True)
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"{name}: {exc}".replace("verts: ", "positions: ")) from None
    try:
        uvs = None if mesh.uvs is None else dequantize_uvs(mesh.uvs, qt)
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"{name}: {exc}".replace("qt: ", f"{qt_name}: ")) from None
    return TexturedMesh(Mesh(verts, mesh.mesh.faces), uvs, mesh.texture, mesh.colors)


def dequantized_pair(ref: TexturedMesh, dis: TexturedMesh, cs: CtcSettings) -> tuple[TexturedMesh, TexturedMesh]:
    """Both frames dequantised over the sequence's box and reindexed (``reindex --sort oriented``).

    Both mmetric steps reindex the dequantised meshes with the same oriented reorder (the grid chain's reindex
    command, IBSM's own reordering): done once here, and IBSM told not to redo it.
    """
    r = oriented_reindex(_dequantized(ref, cs.qp, cs.qt, cs.box, "ref", "qt"))
    d = oriented_reindex(_dequantized(dis, cs.qp, cs.decoded_qt, cs.box, "dis", "decoded_qt"))
    return r, d


def _grid_cloud(m: TexturedMesh, grid_size: int, box: tuple[Corner, Corner]) -> PointCloud:
    return grid_sample(
        m.mesh,
        grid_size,
        use_normal=True,
        box=box,
        texture=m.texture,
        uvs=m.uvs,
        colors=m.colors,
        bilinear=True,
        use_fixed_point=True,
    )


def _timed_ibsm(r: TexturedMesh, d: TexturedMesh, resolution: int, cameras: int) -> tuple[IbsmResult, float]:
    t0 = time.perf_counter()
    # both meshes are already reindexed as IBSM would (the grid chain's reorder is the same)
    out = ibsm(r, d, resolution=resolution, cameras=cameras, reorder=False)
    return out, time.perf_counter() - t0


def ctc_frame(
    ref: TexturedMesh,
    dis: TexturedMesh,
    settings: CtcSettings | None = None,
    *,
    frame: int = 0,
    **keywords: Unpack[CtcKeywords],
) -> CtcFrame:
    """The grid figures of one frame pair, as the CTC's ``mm sequence`` chain computes them (see the module).

    Args:
        ref: the *quantised* source frame (integer positions, quantised UVs) with its texture.
        dis: the decoded frame (integer positions over the same box; UVs already in ``[0, 1]`` unless
            ``decoded_qt >= 7``).
        settings: the chain's settings (:class:`~torchmeshmetric.mpeg.ctc.settings.CtcSettings`), or ``None`` to
            give them as keywords (not both).
        frame: frame number stored in the result.
        **keywords: the settings as separate keywords, the fields of
            :class:`~torchmeshmetric.mpeg.ctc.settings.CtcSettings` with their defaults: ``qp``, ``qt`` (bit depths
            of the positions and the source's UVs), ``min_pos``, ``max_pos`` (the sequence's box), ``resolution``
            (PSNR peak, default the box's longest side), ``decoded_qt`` (0), ``grid_size`` (1024),
            ``ibsm_resolution`` (2048; ``None``: no IBSM), ``ibsm_cameras`` (16).

    Returns:
        :class:`CtcFrame` with ``GridD1``, ``GridD2``, ``IbsmGeom``, ``IbsmLuma`` and, when both carry colour,
        ``GridLuma``, ``GridChromaCb``, ``GridChromaCr``.

    Example:
        >>> import numpy as np, torch, trimesh
        >>> s = trimesh.creation.icosphere(2)
        >>> q = TexturedMesh(Mesh(torch.tensor(np.round((s.vertices + 1) * 511.5)), torch.tensor(s.faces)))
        >>> r = ctc_frame(q, q, qp=10, qt=0, min_pos=[-1, -1, -1], max_pos=[1, 1, 1], resolution=2.0, grid_size=64,
        ...               ibsm_resolution=64)
        >>> r.figures["GridD1"], r.figures["IbsmGeom"]
        (inf, 99.99)
    """
    cs = resolve_settings(settings, **keywords)
    box, grid_size, ibsm_resolution = cs.box, cs.grid_size, cs.ibsm_resolution
    t0 = time.perf_counter()
    r, d = dequantized_pair(ref, dis, cs)
    t1 = time.perf_counter()
    # IBSM, the two samplings and then the comparison release the GIL in their C++ and numpy work: IBSM runs beside
    # the grid chain, so that one's single-threaded parts fill the core the other leaves
    with ThreadPoolExecutor(max_workers=3) as pool:
        ib_job = None if ibsm_resolution is None else pool.submit(_timed_ibsm, r, d, ibsm_resolution, cs.ibsm_cameras)
        rc = pool.submit(_grid_cloud, r, grid_size, box)
        dc = pool.submit(_grid_cloud, d, grid_size, box)
        ref_cloud, dis_cloud = rc.result(), dc.result()
        t2 = time.perf_counter()
        res = mpeg_compare(ref_cloud, dis_cloud, peak=cs.peak)
        t3 = time.perf_counter()
        ib, ibsm_seconds = (None, 0.0) if ib_job is None else ib_job.result()
    figures = {"GridD1": res.symmetric.d1_psnr, "GridD2": res.symmetric.d2_psnr}
    if res.symmetric.color_psnr is not None:
        y, cb, cr = res.symmetric.color_psnr
        figures.update({"GridLuma": y, "GridChromaCb": cb, "GridChromaCr": cr})
    if ib is not None:
        figures.update({"IbsmGeom": ib.geo_psnr, "IbsmLuma": ib.yuv_psnr[0]})
    seconds = {"dequantize": t1 - t0, "grid": t2 - t1, "pcc": t3 - t2, "ibsm": ibsm_seconds}
    return CtcFrame(frame, figures, res.points_ref, res.points_dis, seconds)


def ctc_sequence(
    pairs: Iterable[tuple[int, TexturedMesh, TexturedMesh]],
    settings: CtcSettings | None = None,
    *,
    progress: Callable[[CtcFrame], None] | None = None,
    **keywords: Unpack[CtcKeywords],
) -> CtcSequence:
    """The CTC figures of a decoded sequence: :func:`ctc_frame` on every ``(frame, source, decoded)`` pair.

    ``pairs`` may be a generator that reads the frames lazily (one pair in memory at a time). The settings are
    ``settings`` or the keywords, as for :func:`ctc_frame`; ``progress`` is called with each frame's result.

    Args:
        pairs: ``(frame, source, decoded)`` triples: the frame number, the *quantised* source frame and the
            decoded frame (as :func:`ctc_frame`'s ``ref`` and ``dis``).
        settings: the chain's settings (:class:`~torchmeshmetric.mpeg.ctc.settings.CtcSettings`), or ``None`` to
            give them as keywords (not both).
        progress: called with each :class:`CtcFrame` as it is computed.
        **keywords: the settings as keywords (``qp``, ``qt``, ``min_pos``, ``max_pos``, ...), as for
            :func:`ctc_frame`.

    Returns:
        :class:`CtcSequence`: the frames in the order given and the columns present in any of them
        (:meth:`CtcSequence.mean` gives mmetric's sequence means).

    Raises:
        TypeError: both ``settings`` and a keyword, or a required keyword missing
            (:func:`~torchmeshmetric.mpeg.ctc.settings.resolve_settings`); and :func:`ctc_frame`'s errors.

    Example:
        >>> import numpy as np, torch, trimesh
        >>> s = trimesh.creation.icosphere(2)
        >>> q = TexturedMesh(Mesh(torch.tensor(np.round((s.vertices + 1) * 511.5)), torch.tensor(s.faces)))
        >>> seq = ctc_sequence([(0, q, q)], qp=10, qt=0, min_pos=[-1] * 3, max_pos=[1] * 3, resolution=2.0,
        ...                    grid_size=64, ibsm_resolution=None)
        >>> seq.mean()["GridD1"]
        99.99
    """
    cs = resolve_settings(settings, **keywords)
    frames = []
    for k, ref, dis in pairs:
        f = ctc_frame(ref, dis, cs, frame=k)
        frames.append(f)
        if progress is not None:
            progress(f)
    return CtcSequence(frames, tuple(c for c in CTC_COLUMNS if any(c in f.figures for f in frames)))
