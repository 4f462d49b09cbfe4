"""Slow, obviously-correct numpy references of the temporal metrics (loops over vertices, edges and frames)."""

from __future__ import annotations

import itertools

import numpy as np


def naive_sted(a: np.ndarray, b: np.ndarray, faces: np.ndarray, dt: float, window: int, c: float) -> tuple[float, ...]:
    """STED_s, STED_t, STED of (F, V, 3) arrays, straight from the definitions (docs/temporal.md)."""
    num_frames, num_verts, _ = a.shape
    ring: dict[int, set[int]] = {v: set() for v in range(num_verts)}
    for tri in faces:
        for p, q in itertools.permutations(tri.tolist(), 2):
            if p != q:
                ring[p].add(q)
    edges = sorted({(min(p, q), max(p, q)) for p in ring for q in ring[p]})
    used = [v for v in range(num_verts) if ring[v]]
    sigmas = []
    for f in range(num_frames):
        length = {e: float(np.linalg.norm(a[f, e[0]] - a[f, e[1]])) for e in edges}
        rel = {
            e: abs(float(np.linalg.norm(b[f, e[0]] - b[f, e[1]])) - length[e]) / length[e] if length[e] > 0 else 0.0
            for e in edges
        }
        for v in used:
            hood = ring[v] | {v}
            mine = [e for e in edges if e[0] in hood and e[1] in hood]
            w = np.array([length[e] for e in mine])
            d = np.array([rel[e] for e in mine])
            mean = (w * d).sum() / w.sum()
            sigmas.append(np.sqrt((w * (d - mean) ** 2).sum() / w.sum()))
    spatial = float(np.mean(sigmas))
    first = a[0]
    # D over the vertices the faces use: a vertex no face references takes no part (docs/temporal.md)
    diameter = max(float(np.linalg.norm(first[i] - first[j])) for i in used for j in used)
    t = np.sqrt((((a[1:] - a[:-1]) / diameter) ** 2).sum(-1) + dt * dt)  # (F-1, V)
    t_hat = np.sqrt((((b[1:] - b[:-1]) / diameter) ** 2).sum(-1) + dt * dt)
    rels = []
    for f in range(num_frames - 1):
        frames = range(max(0, f - window), min(num_frames - 2, f + window) + 1)
        for v in used:
            mean = np.mean([t[g, v] for g in frames])
            rels.append(abs(t_hat[f, v] - t[f, v]) / mean)
    temporal = float(np.mean(rels))
    return spatial, temporal, float(np.sqrt(spatial**2 + c**2 * temporal**2))
