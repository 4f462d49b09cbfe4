"""Capture defects: make a clean mesh look like a real captured volumetric-video frame (test fixtures).

Real frames of the paper's size class (about 20.7k vertices / 39.4k triangles) are normalised to about +-1 and hold
duplicate vertices, zero-length edges, degenerate (zero-area) faces and unreferenced vertices; several registration
solvers fail on them unless they are cleaned first. :func:`add_capture_defects` reproduces each of these defects,
deterministically for a seed, without moving the surface (every added face has zero area).
"""

from __future__ import annotations

import numpy as np
import torch

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
        ValueError: a count is negative or ``duplicate_fraction`` is outside ``[0, 1]``.

    Example:
        >>> import trimesh
        >>> clean = as_mesh(trimesh.creation.icosphere(subdivisions=2))
        >>> noisy = add_capture_defects(clean, seed=0)
        >>> noisy.num_verts > clean.num_verts, noisy.num_faces > clean.num_faces
        (True, True)
        >>> float(noisy.verts.abs().max())
        1.0
    """
    m = as_mesh(mesh)
    for name, val in (
        ("num_zero_length_edges", num_zero_length_edges),
        ("num_collinear_faces", num_collinear_faces),
        ("num_repeated_index_faces", num_repeated_index_faces),
        ("num_unreferenced", num_unreferenced),
    ):
        if not isinstance(val, int) or val < 0:
            raise ValueError(f"{name}: expected an int >= 0, found {val!r}")
    if not 0.0 <= duplicate_fraction <= 1.0:
        raise ValueError(f"duplicate_fraction: expected a float in [0, 1], found {duplicate_fraction!r}")
    rng = np.random.default_rng(seed)
    verts = m.verts.detach().cpu().double().numpy().copy()
    faces = m.faces.cpu().numpy().copy()
    num_v, num_f = verts.shape[0], faces.shape[0]
    if normalize and num_v:
        lo, hi = verts.min(0), verts.max(0)
        verts = verts - 0.5 * (lo + hi)
        scale = np.abs(verts).max()
        if scale > 0:
            verts = verts / scale
    new_verts = [verts]
    new_faces = [faces]
    nv = num_v
    # duplicate vertices: re-point every other face corner that uses a chosen vertex
    num_dup = round(duplicate_fraction * num_v)
    if num_dup and num_f:
        dup = rng.choice(num_v, size=num_dup, replace=False)
        copy_of = np.full(num_v, -1, dtype=np.int64)
        copy_of[dup] = nv + np.arange(num_dup)
        new_verts.append(verts[dup])
        nv += num_dup
        flat = faces.reshape(-1)
        hit = np.nonzero(copy_of[flat] >= 0)[0]
        # alternate occurrences of each duplicated vertex: every second one goes to the copy
        order = np.argsort(flat[hit], kind="stable")
        hit_sorted = hit[order]
        vals = flat[hit_sorted]
        first = np.r_[True, vals[1:] != vals[:-1]]
        group_start = np.maximum.accumulate(np.where(first, np.arange(vals.size), 0))
        odd = ((np.arange(vals.size) - group_start) % 2) == 1
        flat = flat.copy()
        flat[hit_sorted[odd]] = copy_of[vals[odd]]
        faces = flat.reshape(-1, 3)
        new_faces[0] = faces
    if num_f:
        # zero-length edges
        if num_zero_length_edges:
            fi = rng.integers(0, num_f, size=num_zero_length_edges)
            a, b = faces[fi, 0], faces[fi, 1]
            new_verts.append(_verts_of(new_verts, a))
            copies = nv + np.arange(num_zero_length_edges)
            nv += num_zero_length_edges
            new_faces.append(np.stack([a, copies, b], 1))
        if num_collinear_faces:
            fi = rng.integers(0, num_f, size=num_collinear_faces)
            a, b = faces[fi, 0], faces[fi, 1]
            all_v = np.concatenate(new_verts)
            new_verts.append(0.5 * (all_v[a] + all_v[b]))
            mids = nv + np.arange(num_collinear_faces)
            nv += num_collinear_faces
            new_faces.append(np.stack([a, mids, b], 1))
        if num_repeated_index_faces:
            fi = rng.integers(0, num_f, size=num_repeated_index_faces)
            new_faces.append(np.stack([faces[fi, 0], faces[fi, 0], faces[fi, 1]], 1))
    if num_unreferenced:
        all_v = np.concatenate(new_verts)
        lo, hi = all_v.min(0), all_v.max(0)
        new_verts.append(lo + rng.random((num_unreferenced, 3)) * (hi - lo))
        nv += num_unreferenced
    out_v = np.concatenate(new_verts)
    out_f = np.concatenate(new_faces)
    if shuffle:
        perm = rng.permutation(out_v.shape[0])
        inv = np.empty_like(perm)
        inv[perm] = np.arange(perm.size)
        out_v = out_v[perm]
        out_f = inv[out_f][rng.permutation(out_f.shape[0])]
    return Mesh(
        torch.from_numpy(out_v).to(device=m.device, dtype=m.dtype),
        torch.from_numpy(out_f).to(m.device),
        validate=False,
    )


def _verts_of(chunks: list[np.ndarray], idx: np.ndarray) -> np.ndarray:
    """Rows ``idx`` of the concatenation of ``chunks`` (vertex arrays built so far)."""
    return np.concatenate(chunks)[idx]
