"""Capture defects: make a clean mesh look like a real captured volumetric-video frame (test fixtures).

Real frames of the paper's size class (about 20.7k vertices / 39.4k triangles) are normalised to about +-1 and hold
duplicate vertices, zero-length edges, degenerate (zero-area) faces and unreferenced vertices; several registration
solvers fail on them unless they are cleaned first. :func:`add_capture_defects` reproduces each of these defects,
deterministically for a seed, without moving the surface (every added face has zero area).
"""

from __future__ import annotations

import numpy as np
import torch

from torchmeshmetric._checks import check_flag, check_int, check_real
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = ["add_capture_defects"]


def add_capture_defects(
    mesh: MeshLike,
    *,
    seed: int = 0,
    normalize: bool = True,
    duplicate_fraction: float = 0.02,
    num_zero_length_edges: int = 20,
    num_collinear_faces: int = 20,
    num_repeated_index_faces: int = 5,
    num_unreferenced: int = 20,
    shuffle: bool = True,
) -> Mesh:
    """Return a copy of ``mesh`` with the defects of captured frames; the surface itself is unchanged.

    Defects added (each count may be 0):

    - **normalisation**: vertices centred on the bounding-box centre and scaled so that the largest coordinate is 1;
    - **duplicate vertices**: ``duplicate_fraction`` of the vertices get a copy at the same position, and half of the
      faces around each original are re-pointed to the copy (an open seam, as UV seams leave in captured meshes);
    - **zero-length edges**: faces ``(a, a', b)`` where ``a'`` is a new copy of ``a`` (coincident, distinct indices);
    - **collinear faces**: faces ``(a, m, b)`` with ``m`` the midpoint of an edge ``ab`` (zero area, non-zero edges);
    - **repeated-index faces**: faces ``(a, a, b)``;
    - **unreferenced vertices**: points inside the bounding box that no face uses;
    - **shuffle**: vertex and face order permuted, so defects are not all at the end.

    Args:
        mesh: the clean mesh.
        seed: seed of the random choices.
        normalize: apply the normalisation.
        duplicate_fraction: fraction of vertices duplicated, in ``[0, 1]``.
        num_zero_length_edges: number of faces with a zero-length edge.
        num_collinear_faces: number of collinear zero-area faces.
        num_repeated_index_faces: number of faces repeating an index.
        num_unreferenced: number of unreferenced vertices.
        shuffle: permute vertex and face order.

    Returns:
        The defective mesh (same dtype and device as the input).

    Raises:
        TypeError: a count or ``seed`` is not an int, or ``duplicate_fraction`` is not a number.
        ValueError: a count or ``seed`` is negative, or ``duplicate_fraction`` is outside ``[0, 1]``.

    Example:
        >>> import trimesh
        >>> clean = as_mesh(trimesh.creation.icosphere(subdivisions=2))
        >>> noisy = add_capture_defects(clean, seed=0)
        >>> noisy.num_verts > clean.num_verts, noisy.num_faces > clean.num_faces
        (True, True)
        >>> float(noisy.verts.abs().max())
        1.0
    """
    normalize = check_flag(normalize, "normalize")
    shuffle = check_flag(shuffle, "shuffle")
    m = as_mesh(mesh)
    for name, val in (
        ("num_zero_length_edges", num_zero_length_edges),
        ("num_collinear_faces", num_collinear_faces),
        ("num_repeated_index_faces", num_repeated_index_faces),
        ("num_unreferenced", num_unreferenced),
    ):
        check_int(val, name, 0)
    if not 0.0 <= check_real(duplicate_fraction, "duplicate_fraction") <= 1.0:
        raise ValueError(f"duplicate_fraction: expected a float in [0, 1], found {duplicate_fraction!r}")
    rng = np.random.default_rng(check_int(seed, "seed", 0))  # numpy's SeedSequence named no argument
    verts = m.verts.detach().cpu().double().numpy().copy()
    faces = m.faces.cpu().numpy().copy()
    if normalize and verts.shape[0]:
        verts = _normalised(verts)
    # The random choices are drawn in this order for a given seed: duplicates, zero-area faces, unreferenced points,
    # then the shuffles.
    verts, faces = _with_duplicates(verts, faces, round(duplicate_fraction * verts.shape[0]), rng)
    verts, faces = _with_zero_area_faces(
        verts, faces, num_zero_length_edges, num_collinear_faces, num_repeated_index_faces, rng
    )
    if num_unreferenced:
        lo, hi = verts.min(0), verts.max(0)
        verts = np.concatenate([verts, lo + rng.random((num_unreferenced, 3)) * (hi - lo)])
    if shuffle:
        perm = rng.permutation(verts.shape[0])
        inv = np.empty_like(perm)
        inv[perm] = np.arange(perm.size)
        verts = verts[perm]
        faces = inv[faces][rng.permutation(faces.shape[0])]
    return Mesh(
        torch.from_numpy(verts).to(device=m.device, dtype=m.dtype),
        torch.from_numpy(faces).to(m.device),
        validate=False,
    )


def _normalised(verts: np.ndarray) -> np.ndarray:
    """Centred on the bounding-box centre, scaled so that the largest coordinate is 1 (unless all are 0)."""
    lo, hi = verts.min(0), verts.max(0)
    verts = verts - 0.5 * (lo + hi)
    scale = np.abs(verts).max()
    return verts / scale if scale > 0 else verts


def _with_duplicates(
    verts: np.ndarray, faces: np.ndarray, num_dup: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """``num_dup`` random vertices copied; every second face corner using one of them re-pointed to its copy."""
    num_v = verts.shape[0]
    if not (num_dup and faces.shape[0]):
        return verts, faces
    dup = rng.choice(num_v, size=num_dup, replace=False)
    copy_of = np.full(num_v, -1, dtype=np.int64)
    copy_of[dup] = num_v + np.arange(num_dup)
    flat = faces.reshape(-1)
    hit = np.nonzero(copy_of[flat] >= 0)[0]
    # Alternate occurrences of each duplicated vertex: every second one goes to the copy.
    order = np.argsort(flat[hit], kind="stable")
    hit_sorted = hit[order]
    vals = flat[hit_sorted]
    first = np.r_[True, vals[1:] != vals[:-1]]
    group_start = np.maximum.accumulate(np.where(first, np.arange(vals.size), 0))
    odd = ((np.arange(vals.size) - group_start) % 2) == 1
    flat = flat.copy()
    flat[hit_sorted[odd]] = copy_of[vals[odd]]
    return np.concatenate([verts, verts[dup]]), flat.reshape(-1, 3)


def _with_zero_area_faces(
    verts: np.ndarray, faces: np.ndarray, num_zero_length: int, num_collinear: int, num_repeated: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Zero-area faces on the first edge ``ab`` of random faces, appended after ``faces``.

    ``(a, a', b)`` with ``a'`` a new copy of ``a``, ``(a, m, b)`` with ``m`` a new midpoint, and ``(a, a, b)``.
    """
    num_f = faces.shape[0]
    if not num_f:
        return verts, faces
    added = [faces]
    if num_zero_length:
        fi = rng.integers(0, num_f, size=num_zero_length)
        a, b = faces[fi, 0], faces[fi, 1]
        added.append(np.stack([a, verts.shape[0] + np.arange(num_zero_length), b], 1))
        verts = np.concatenate([verts, verts[a]])
    if num_collinear:
        fi = rng.integers(0, num_f, size=num_collinear)
        a, b = faces[fi, 0], faces[fi, 1]
        added.append(np.stack([a, verts.shape[0] + np.arange(num_collinear), b], 1))
        verts = np.concatenate([verts, 0.5 * (verts[a] + verts[b])])
    if num_repeated:
        fi = rng.integers(0, num_f, size=num_repeated)
        added.append(np.stack([faces[fi, 0], faces[fi, 0], faces[fi, 1]], 1))
    return verts, np.concatenate(added)
