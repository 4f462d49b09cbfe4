"""Test-only fixture: inject the defects of frames as they come out of capture into a clean mesh.

Duplicate vertices (faces re-pointed to a copy, so the surface is split along seams), zero-length edges (faces
using two copies of one position), degenerate faces (repeated indices and collinear triples) and unreferenced
vertices (some far away). The surface itself is unchanged.
"""

from __future__ import annotations

import numpy as np


def inject_capture_defects(
    verts: np.ndarray, faces: np.ndarray, *, seed: int = 0, fraction: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    v = np.asarray(verts, dtype=np.float64).copy()
    f = np.asarray(faces, dtype=np.int64).copy()
    nv, nf = len(v), len(f)
    k = max(1, int(fraction * nv))
    # Duplicate vertices: copy k vertices and re-point one corner of some of their faces to the copy.
    dup = rng.choice(nv, size=k, replace=False)
    new_ids = nv + np.arange(k)
    v = np.concatenate([v, v[dup]])
    remap = dict(zip(dup.tolist(), new_ids.tolist(), strict=True))
    for fi in rng.choice(nf, size=min(nf, 3 * k), replace=False):
        for c in range(3):
            if int(f[fi, c]) in remap and rng.random() < 0.5:
                f[fi, c] = remap[int(f[fi, c])]
    # Zero-length edges: faces over a vertex and its duplicate (zero area).
    zl = np.stack([dup[: k // 2], new_ids[: k // 2], f[rng.choice(nf, size=k // 2), 0]], 1)
    # Degenerate faces: repeated indices and collinear triples (midpoint vertex appended).
    rep = f[rng.choice(nf, size=k // 2)]
    rep[:, 2] = rep[:, 1]
    e = f[rng.choice(nf, size=k // 2)]
    mids = 0.5 * (v[e[:, 0]] + v[e[:, 1]])
    mid_ids = len(v) + np.arange(len(mids))
    v = np.concatenate([v, mids])
    col = np.stack([e[:, 0], e[:, 1], mid_ids], 1)
    # Unreferenced vertices: a few at the origin, near the surface and far away.
    extra = np.concatenate([np.zeros((3, 3)), v[rng.choice(nv, size=5)] + 0.01, 50.0 * rng.standard_normal((3, 3))])
    v = np.concatenate([v, extra])
    f = np.concatenate([f, zl, rep, col])
    f = f[rng.permutation(len(f))]
    return v, f
