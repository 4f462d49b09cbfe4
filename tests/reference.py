"""Slow, obviously-correct float64 references for the kernels (pure Python / numpy; no torch)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np


def _closest_on_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    den = float(ab @ ab)
    if den == 0.0:
        return a.copy()
    t = min(1.0, max(0.0, float((p - a) @ ab) / den))
    return a + t * ab


def closest_point_triangle(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Ericson 2004, *Real-Time Collision Detection*, ClosestPtPointTriangle (§5.1.5), transcribed branch by branch.

    Degenerate (zero-area) triangles are segments or points: their closest point is the nearest of the three edge
    segments' closest points.
    """
    p, a, b, c = (np.asarray(x, dtype=np.float64) for x in (p, a, b, c))
    ab, ac, ap = b - a, c - a, p - a
    if float(np.cross(ab, ac) @ np.cross(ab, ac)) == 0.0:
        cands = [_closest_on_segment(p, a, b), _closest_on_segment(p, a, c), _closest_on_segment(p, b, c)]
        return min(cands, key=lambda q: float((p - q) @ (p - q)))
    d1, d2 = ab @ ap, ac @ ap
    if d1 <= 0 and d2 <= 0:
        return a  # vertex region A
    bp = p - b
    d3, d4 = ab @ bp, ac @ bp
    if d3 >= 0 and d4 <= d3:
        return b  # vertex region B
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        return a + d1 / (d1 - d3) * ab  # edge region AB
    cp = p - c
    d5, d6 = ab @ cp, ac @ cp
    if d6 >= 0 and d5 <= d6:
        return c  # vertex region C
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        return a + d2 / (d2 - d6) * ac  # edge region AC
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b)  # edge region BC
    denom = 1.0 / (va + vb + vc)
    return a + ab * (vb * denom) + ac * (vc * denom)  # face region


def closest_point_triangle_exact(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """:func:`closest_point_triangle` in exact rational arithmetic (``Fraction``), rounded once at the end.

    Ericson's ``vc = d1 d4 - d3 d2`` cancels catastrophically on slivers in float64 (a point on the long edge of a
    1e-7-wide triangle comes out ~5e-9 away); with exact arithmetic every branch and division is exact, so this is
    the oracle for property tests over arbitrary triangles. Slow: for a few points only.
    """
    pf, af, bf, cf = ([Fraction(float(v)) for v in x] for x in (p, a, b, c))

    def sub(x: list[Fraction], y: list[Fraction]) -> list[Fraction]:
        return [xi - yi for xi, yi in zip(x, y, strict=True)]

    def dot(x: list[Fraction], y: list[Fraction]) -> Fraction:
        return sum((xi * yi for xi, yi in zip(x, y, strict=True)), Fraction(0))

    def along(x: list[Fraction], t: Fraction, d: list[Fraction]) -> list[Fraction]:
        return [xi + t * di for xi, di in zip(x, d, strict=True)]

    def on_segment(x: list[Fraction], y: list[Fraction]) -> list[Fraction]:
        d = sub(y, x)
        den = dot(d, d)
        return x if den == 0 else along(x, min(Fraction(1), max(Fraction(0), dot(sub(pf, x), d) / den)), d)

    ab, ac, ap, bp, cp = sub(bf, af), sub(cf, af), sub(pf, af), sub(pf, bf), sub(pf, cf)
    n = [ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]]
    if dot(n, n) == 0:
        cands = [on_segment(af, bf), on_segment(af, cf), on_segment(bf, cf)]
        q = min(cands, key=lambda x: dot(sub(pf, x), sub(pf, x)))
    else:
        d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), dot(ac, cp)
        va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
        if d1 <= 0 and d2 <= 0:
            q = af
        elif d3 >= 0 and d4 <= d3:
            q = bf
        elif vc <= 0 and d1 >= 0 and d3 <= 0:
            q = along(af, d1 / (d1 - d3), ab)
        elif d6 >= 0 and d5 <= d6:
            q = cf
        elif vb <= 0 and d2 >= 0 and d6 <= 0:
            q = along(af, d2 / (d2 - d6), ac)
        elif va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
            q = along(bf, (d4 - d3) / ((d4 - d3) + (d5 - d6)), sub(cf, bf))
        else:
            q = along(along(af, vb / (va + vb + vc), ab), vc / (va + vb + vc), ac)
    return np.array([float(v) for v in q])


def point_mesh_distance(points: np.ndarray, verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from each point to the mesh by testing every face; returns (dists, closest)."""
    points, verts = np.asarray(points, np.float64), np.asarray(verts, np.float64)
    dists = np.empty(len(points))
    closest = np.empty((len(points), 3))
    for i, p in enumerate(points):
        best, best_q = np.inf, None
        for f in faces:
            q = closest_point_triangle(p, verts[f[0]], verts[f[1]], verts[f[2]])
            d = float(np.sqrt((p - q) @ (p - q)))
            if d < best:
                best, best_q = d, q
        dists[i], closest[i] = best, best_q
    return dists, closest


def nearest_vertex(points: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Brute-force nearest neighbour in float64; returns (dists, idx) with the lowest index among ties."""
    points, ref = np.asarray(points, np.float64), np.asarray(ref, np.float64)
    d = np.sqrt(((points[:, None, :] - ref[None, :, :]) ** 2).sum(-1))
    idx = d.argmin(1)
    return d[np.arange(len(points)), idx], idx


def round_to_binary(q: Fraction, dtype: np.dtype | type) -> float:
    """``q`` rounded once, to nearest even, to ``dtype`` (float32 or float64; normal numbers), as a Python float.

    ``float(q)`` rounds to float64 correctly, but float64 then float32 would round twice.
    """
    bits = np.finfo(dtype).nmant + 1
    if q == 0:
        return 0.0
    sign, q = (-1.0 if q < 0 else 1.0), abs(q)
    e = q.numerator.bit_length() - q.denominator.bit_length()
    scaled = q * Fraction(2) ** (bits - 1 - e)
    while scaled >= 2**bits:
        e, scaled = e + 1, scaled / 2
    while scaled < 2 ** (bits - 1):
        e, scaled = e - 1, scaled * 2
    whole, rest = divmod(scaled.numerator, scaled.denominator)
    if 2 * rest > scaled.denominator or (2 * rest == scaled.denominator and whole % 2 == 1):
        whole += 1
    return sign * float(whole) * 2.0 ** (e - bits + 1)


def fma(a: float, b: float, c: float, dtype: np.dtype | type) -> float:
    """``a * b + c`` rounded once to ``dtype`` (IEEE 754 fusedMultiplyAdd, as ``std::fma``)."""
    return round_to_binary(Fraction(a) * Fraction(b) + Fraction(c), dtype)


def fused_unit_vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals ``(V, 3)`` in ``verts``' dtype, rounded as IEEE 754 defines every step.

    Face cross products ``(b - a) x (c - a)`` as ``fma(u1, v2, -(u2 v1))`` per component, summed per vertex in (corner,
    face) order, divided by ``sqrt(fma(z, z, fma(y, y, x x)))`` (correctly rounded; zero where that is zero): the C++
    ``deform_normals``'s operations, each rounded once as IEEE 754 defines, with no library kernel in between, so the
    same bits on every CPU. Slow (exact rational fma): a few thousand faces.
    """
    dt = verts.dtype.type
    a, b, c = (verts[faces[:, i]] for i in range(3))
    u, v = (b - a).tolist(), (c - a).tolist()
    cross = np.array(
        [
            [fma(p[j], q[k], -float(dt(p[k]) * dt(q[j])), dt) for j, k in ((1, 2), (2, 0), (0, 1))]
            for p, q in zip(u, v, strict=True)
        ],
        dtype=dt,
    ).reshape(-1, 3)
    acc = np.zeros_like(verts)
    for corner in range(3):
        np.add.at(acc, faces[:, corner], cross)  # unbuffered: in index order
    out = np.zeros_like(verts)
    for i, (x, y, z) in enumerate(acc.tolist()):
        s = fma(z, z, fma(y, y, float(dt(x) * dt(x)), dt), dt)
        norm = dt(math.sqrt(s))  # sqrt in float64 then float32 is correctly rounded (53 >= 2 * 24 + 2)
        if norm > 0:
            out[i] = acc[i] / norm
    return out
