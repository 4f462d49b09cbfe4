"""Per-face errors of a decoded frame: its CTC grid samples' D1, D2 and colour errors, gathered on the faces.

What mmetric's per-point output (m69466) shows, through the library only, on the mesh a viewer draws. The frame pair
goes through the CTC chain of :func:`~torchmeshmetric.mpeg.ctc.chain.ctc_frame` (fixed-point dequantisation, oriented
reindex, grid sampling over the sequence's box, duplicate merging) and :func:`~torchmeshmetric.mpeg.comparison.pcc.
mpeg_point_errors` gives every merged sample its errors against the other cloud (the terms of the frame's MSEs).
Each face of the *decoded* mesh (``side="decoded"``: the ``dis -> ref`` direction) or of the source (``"source"``:
``ref -> dis``) then gets the mean and the largest error of the samples it produced: squared point-to-point distance
(D1), squared point-to-plane error (D2) and squared Y, Cb, Cr differences (colours in ``[0, 1]``). A sample shared
by several faces (mmetric keeps one) counts for the face that produced it first; faces with no sample hold NaN.
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from torchmeshmetric._atomic import atomic_write
from torchmeshmetric._checks import check_flag
from torchmeshmetric.mpeg.comparison.pcc import mpeg_point_errors
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.mpeg.ctc.chain import dequantized_pair
from torchmeshmetric.mpeg.ctc.settings import Corner, CtcSettings, resolve_settings
from torchmeshmetric.mpeg.sampling.grid_sampling import grid_sample_faces
from torchmeshmetric.structures import Mesh

__all__ = ["FaceErrors", "ctc_face_errors", "write_face_errors_csv", "write_face_errors_ply"]

_SIDES = ("decoded", "source")


class FaceErrors(NamedTuple):
    """Errors per face of one frame (see the module).

    Attributes:
        mesh: the faces' mesh: the decoded (or source) frame dequantised and reindexed as the chain samples it.
        samples: ``(F,)`` grid samples of each face.
        d1_mean, d1_max: ``(F,)`` mean and largest squared point-to-point error (NaN without samples).
        d2_mean, d2_max: ``(F,)`` the same of the squared point-to-plane error.
        color_mean, color_max: ``(F, 3)`` the same of the squared Y, Cb, Cr errors, or ``None`` without colour.

    Example:
        >>> import numpy as np, torch, trimesh
        >>> from torchmeshmetric import Mesh
        >>> from torchmeshmetric.mpeg import TexturedMesh
        >>> s = trimesh.creation.icosphere(2)
        >>> q = TexturedMesh(Mesh(torch.tensor(np.round((s.vertices + 1) * 511.5)), torch.tensor(s.faces)))  # 10 bits
        >>> e = ctc_face_errors(q, q, qp=10, qt=0, min_pos=[-1] * 3, max_pos=[1] * 3, grid_size=64)
        >>> e.mesh.num_faces, e.samples.shape, float(np.nanmax(e.d1_max)), e.color_mean  # identical: no error
        (320, (320,), 0.0, None)
    """

    mesh: Mesh
    samples: np.ndarray
    d1_mean: np.ndarray
    d1_max: np.ndarray
    d2_mean: np.ndarray
    d2_max: np.ndarray
    color_mean: np.ndarray | None
    color_max: np.ndarray | None


def _merged_index(samples: np.ndarray, merged: np.ndarray) -> np.ndarray:
    """For each sample, the row of ``merged`` (the cloud after duplicate merging) at its position."""
    both = np.concatenate([merged, samples]).astype(np.float32) + np.float32(0.0)  # -0.0 and 0.0: one position
    _, inverse = np.unique(both, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    group_to_merged = np.empty(int(inverse.max()) + 1, np.int64)
    group_to_merged[inverse[: merged.shape[0]]] = np.arange(merged.shape[0])
    return group_to_merged[inverse[merged.shape[0] :]]


def _per_face(values: np.ndarray, face: np.ndarray, num_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and max of ``values`` (N,) or (N, k) grouped by ``face``; NaN for faces without values."""
    v = values.reshape(values.shape[0], -1)
    count = np.bincount(face, minlength=num_faces).astype(np.float64)
    sums = np.stack([np.bincount(face, weights=v[:, j], minlength=num_faces) for j in range(v.shape[1])], 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = sums.astype(np.float64) / count[:, None]
    high = np.full((num_faces, v.shape[1]), -np.inf)
    np.maximum.at(high, face, v)
    high[count == 0] = np.nan
    shape = (num_faces,) if values.ndim == 1 else (num_faces, v.shape[1])
    return mean.reshape(shape), high.reshape(shape)


def ctc_face_errors(
    ref: TexturedMesh,
    dis: TexturedMesh,
    settings: CtcSettings | None = None,
    *,
    qp: int | None = None,
    qt: int | None = None,
    min_pos: Corner | None = None,
    max_pos: Corner | None = None,
    decoded_qt: int = 0,
    grid_size: int = 1024,
    side: str = "decoded",
) -> FaceErrors:
    """The per-face errors of a frame pair through the CTC chain (arguments as :func:`~torchmeshmetric.mpeg.ctc_frame`).

    Args:
        ref: the quantised source frame with its texture.
        dis: the decoded frame.
        settings: the chain's settings (:class:`~torchmeshmetric.mpeg.ctc.settings.CtcSettings`; its PSNR peak and
            IBSM settings are not used), or ``None`` to give them as the keywords below (not both).
        qp: geometry bit depth of both frames.
        qt: UV bit depth of the source.
        min_pos: ``(3,)`` the sequence box's min corner.
        max_pos: ``(3,)`` its max corner.
        decoded_qt: UV bit depth of the decoded frame (the test model: 0).
        grid_size: ``--gridSize`` (1024).
        side: ``"decoded"``: errors on the decoded mesh's faces (its samples against the source's);
            ``"source"``: on the source's faces.

    Returns:
        :class:`FaceErrors`.

    Raises:
        ValueError: an unknown ``side`` (and what ``ctc_frame`` raises for bad inputs).

    Example:
        >>> import torch, trimesh
        >>> s = trimesh.creation.icosphere(2)
        >>> q = TexturedMesh(Mesh(torch.tensor(np.round((s.vertices + 1) * 511.5)), torch.tensor(s.faces)))
        >>> e = ctc_face_errors(q, q, qp=10, qt=0, min_pos=[-1] * 3, max_pos=[1] * 3, grid_size=64)
        >>> int(e.samples.sum()) > 0, float(np.nanmax(e.d1_max))
        (True, 0.0)
    """
    if side not in _SIDES:
        raise ValueError(f"side: expected 'decoded' or 'source', found {side!r}")
    cs = resolve_settings(settings, qp=qp, qt=qt, min_pos=min_pos, max_pos=max_pos, decoded_qt=decoded_qt,
                          grid_size=grid_size)  # fmt: skip
    r, d = dequantized_pair(ref, dis, cs)
    sampled = [
        grid_sample_faces(
            m.mesh,
            cs.grid_size,
            box=cs.box,
            texture=m.texture,
            uvs=m.uvs,
            colors=m.colors,
            bilinear=True,
            use_fixed_point=True,
        )
        for m in (r, d)
    ]
    errors = mpeg_point_errors(sampled[0].cloud, sampled[1].cloud)
    mine, merged, per_point, mesh = (
        (sampled[1], errors.dis, errors.dis_to_ref, d.mesh)
        if side == "decoded"
        else (sampled[0], errors.ref, errors.ref_to_dis, r.mesh)
    )
    at = _merged_index(mine.cloud.points.numpy(), merged.points.numpy())
    n = int(mesh.faces.shape[0])
    face = np.asarray(mine.face_idx, np.int64)
    d1 = _per_face(per_point.d1[at], face, n)
    nan = np.full(n, np.nan)
    d2 = (nan, nan) if per_point.d2 is None else _per_face(per_point.d2[at], face, n)
    col: tuple[Any, Any] = (None, None) if per_point.color is None else _per_face(per_point.color[at], face, n)
    return FaceErrors(mesh, np.bincount(face, minlength=n), d1[0], d1[1], d2[0], d2[1], col[0], col[1])


def _columns(e: FaceErrors) -> list[tuple[str, np.ndarray]]:
    cols = [
        ("samples", e.samples),
        ("d1_mean", e.d1_mean),
        ("d1_max", e.d1_max),
        ("d2_mean", e.d2_mean),
        ("d2_max", e.d2_max),
    ]
    if e.color_mean is not None and e.color_max is not None:
        for j, c in enumerate(("y", "cb", "cr")):
            cols += [(f"{c}_mean", e.color_mean[:, j]), (f"{c}_max", e.color_max[:, j])]
    return cols


def write_face_errors_csv(path: str | os.PathLike[str], errors: FaceErrors, *, overwrite: bool = False) -> Path:
    """One row per face: ``face, v0, v1, v2`` (the PLY's vertex indices), then the errors (empty without samples).

    Written atomically; refuses to replace a file unless ``overwrite``.
    """
    overwrite = check_flag(overwrite, "overwrite")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    cols = _columns(errors)
    w.writerow(["face", "v0", "v1", "v2", *(name for name, _ in cols)])
    faces = errors.mesh.faces.numpy()
    for i in range(faces.shape[0]):
        cells = [
            str(int(v[i])) if name == "samples" else ("" if np.isnan(v[i]) else repr(float(v[i]))) for name, v in cols
        ]
        w.writerow([i, *faces[i].tolist(), *cells])
    return atomic_write(path, buf.getvalue(), overwrite=overwrite)


def write_face_errors_ply(
    path: str | os.PathLike[str],
    errors: FaceErrors,
    *,
    color_by: str = "d1_mean",
    vmax: float | None = None,
    overwrite: bool = False,
) -> Path:
    """A binary PLY of the faces' mesh with every error as a face property, and a face colour from ``color_by``.

    The colour is the library's error scale (:func:`~torchmeshmetric.viz.error_colors`: dark blue at 0, yellow at
    ``vmax``, default the 95th percentile); faces without samples are grey. Properties: ``samples`` (int) and the
    errors (double) of :func:`write_face_errors_csv`'s columns, so a viewer can colour by any of them.

    Raises:
        ValueError: ``color_by`` is not one of the error columns.
    """
    overwrite = check_flag(overwrite, "overwrite")
    import torch

    from torchmeshmetric.viz.colors import error_colors

    cols = _columns(errors)
    names = [name for name, _ in cols]
    if color_by not in names or color_by == "samples":
        raise ValueError(f"color_by: expected one of {', '.join(names[1:])}, found {color_by!r}")
    values = dict(cols)[color_by]
    has = ~np.isnan(values)
    rgb = np.full((values.shape[0], 3), 128, np.uint8)
    if has.any():
        rgb[has] = error_colors(torch.from_numpy(values[has]), vmax).numpy()[:, :3]
    verts = errors.mesh.verts.detach().cpu().numpy().astype(np.float32)
    faces = errors.mesh.faces.numpy()
    header = [
        "ply",
        "format binary_little_endian 1.0",
        "comment torchmeshmetric CTC per-face errors",
        f"element vertex {verts.shape[0]}",
        "property float x",
        "property float y",
        "property float z",
        f"element face {faces.shape[0]}",
        "property list uchar int vertex_indices",
        "property uchar red",
        "property uchar green",
        "property uchar blue",
        "property int samples",
        *(f"property double {name}" for name in names[1:]),
        "end_header",
    ]
    face_dtype = np.dtype(
        [("n", "u1"), ("idx", "<i4", 3), ("rgb", "u1", 3), ("samples", "<i4"), *((name, "<f8") for name in names[1:])]
    )
    rows = np.zeros(faces.shape[0], face_dtype)
    rows["n"], rows["idx"], rows["rgb"], rows["samples"] = 3, faces, rgb, errors.samples
    for name, v in cols[1:]:
        rows[name] = v
    data = ("\n".join(header) + "\n").encode() + verts.astype("<f4").tobytes() + rows.tobytes()
    return atomic_write(path, data, overwrite=overwrite)
