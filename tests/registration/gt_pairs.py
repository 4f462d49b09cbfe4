"""Ground-truth registration pairs: a stick-figure performer, a known smooth deformation, an independent remesh.

The source is the marching-cubes mesh of a smooth union of capsules (torso, head, arms, legs). A known smooth,
invertible deformation ``phi`` (an angular-sector rotation of an arm about its shoulder, a twist of the upper body)
moves every source vertex to its ground-truth position ``phi(v)``. The target is meshed *independently*: marching
cubes of ``sdf(phi^-1(x))`` on another grid (other spacing, shifted origin), whose zero level set is exactly the
deformed surface, so no vertex correspondence survives. Test data only.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import torch
from skimage.measure import marching_cubes


def _capsule(x: torch.Tensor, a: tuple[float, ...], b: tuple[float, ...], r: float) -> torch.Tensor:
    a_t, b_t = torch.tensor(a, dtype=x.dtype), torch.tensor(b, dtype=x.dtype)
    pa, ba = x - a_t, b_t - a_t
    h = ((pa @ ba) / (ba @ ba)).clamp(0, 1)
    return (pa - h[:, None] * ba).norm(dim=-1) - r


def figure_sdf(x: torch.Tensor, k: float = 0.04) -> torch.Tensor:
    """Smooth union (log-sum-exp, width ``k``) of the performer's capsules; negative inside."""
    parts = [
        _capsule(x, (0.0, 0.0, -0.25), (0.0, 0.0, 0.3), 0.19),  # torso
        _capsule(x, (0.0, 0.0, 0.58), (0.0, 0.02, 0.66), 0.12),  # head
        _capsule(x, (0.2, 0.0, 0.32), (0.78, 0.05, 0.32), 0.07),  # right arm
        _capsule(x, (-0.2, 0.0, 0.32), (-0.74, -0.06, 0.28), 0.07),  # left arm
        _capsule(x, (0.1, 0.0, -0.35), (0.16, 0.03, -0.98), 0.09),  # right leg
        _capsule(x, (-0.1, 0.0, -0.35), (-0.15, -0.02, -0.98), 0.09),  # left leg
    ]
    d = torch.stack(parts, 1)
    return -k * torch.logsumexp(-d / k, dim=1)


def _smoothstep(e0: float, e1: float, x: torch.Tensor) -> torch.Tensor:
    t = ((x - e0) / (e1 - e0)).clamp(0, 1)
    return t * t * (3 - 2 * t)


@dataclass
class SectorRotation:
    """Rotation about ``axis`` through ``center`` by ``theta * w(alpha)``, ``alpha`` the polar angle from ``ref``.

    ``w = 1`` for ``|alpha| < inner``, 0 beyond ``outer`` (smoothstep between), so one limb turns about its joint
    while the body stays. Invertible when ``|theta| * 1.5 / (outer - inner) < 1`` (monotone angle map).
    """

    center: tuple[float, float, float]
    axis: tuple[float, float, float]
    ref: tuple[float, float, float]
    theta: float
    inner: float
    outer: float

    def _frame(self, x: torch.Tensor) -> tuple[torch.Tensor, ...]:
        a = torch.tensor(self.axis, dtype=x.dtype)
        a = a / a.norm()
        e1 = torch.tensor(self.ref, dtype=x.dtype)
        e1 = e1 - (e1 @ a) * a
        e1 = e1 / e1.norm()
        e2 = torch.linalg.cross(a, e1)
        r = x - torch.tensor(self.center, dtype=x.dtype)
        return a, e1, e2, r @ a, r @ e1, r @ e2

    def _w(self, alpha: torch.Tensor) -> torch.Tensor:
        return 1 - _smoothstep(self.inner, self.outer, alpha.abs())

    def _apply(self, x: torch.Tensor, inverse: bool) -> torch.Tensor:
        a, e1, e2, h, u, v = self._frame(x)
        rho, alpha = torch.hypot(u, v), torch.atan2(v, u)
        if not inverse:
            beta = alpha + self.theta * self._w(alpha)
        else:  # solve beta + theta w(beta) = alpha by bisection (monotone)
            lo = alpha - max(self.theta, 0.0)
            hi = alpha - min(self.theta, 0.0)
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                f = mid + self.theta * self._w(mid) - alpha
                lo, hi = torch.where(f < 0, mid, lo), torch.where(f < 0, hi, mid)
            beta = 0.5 * (lo + hi)
        c = torch.tensor(self.center, dtype=x.dtype)
        return c + h[:, None] * a + (rho * torch.cos(beta))[:, None] * e1 + (rho * torch.sin(beta))[:, None] * e2

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self._apply(x, False)

    def inverse(self, x: torch.Tensor) -> torch.Tensor:
        return self._apply(x, True)


@dataclass
class Twist:
    """Rotation about ``axis`` through ``center`` by ``theta * smoothstep(h0, h1, height)`` (height is preserved)."""

    center: tuple[float, float, float]
    axis: tuple[float, float, float]
    theta: float
    h0: float
    h1: float

    def _apply(self, x: torch.Tensor, sign: float) -> torch.Tensor:
        a = torch.tensor(self.axis, dtype=x.dtype)
        a = a / a.norm()
        c = torch.tensor(self.center, dtype=x.dtype)
        r = x - c
        h = r @ a
        ang = sign * self.theta * _smoothstep(self.h0, self.h1, h)
        cos, sin = torch.cos(ang)[:, None], torch.sin(ang)[:, None]
        par = h[:, None] * a
        perp = r - par
        return c + par + perp * cos + torch.linalg.cross(a.expand_as(perp), perp) * sin

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self._apply(x, 1.0)

    def inverse(self, x: torch.Tensor) -> torch.Tensor:
        return self._apply(x, -1.0)


@dataclass
class Compose:
    """``parts[-1] o ... o parts[0]``."""

    parts: list

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        for p in self.parts:
            x = p.forward(x)
        return x

    def inverse(self, x: torch.Tensor) -> torch.Tensor:
        for p in reversed(self.parts):
            x = p.inverse(x)
        return x


MOTIONS = {"small": (10.0, 8.0, 0.0), "medium": (25.0, 15.0, -10.0), "large": (55.0, 30.0, -30.0)}
"""Level -> (right-arm sector rotation, upper-body twist, left-arm rotation), degrees."""


def deformation(level: str) -> Compose:
    arm, twist, left = (math.radians(d) for d in MOTIONS[level])
    parts: list = [
        SectorRotation((0.2, 0.0, 0.32), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0), arm, math.radians(12), math.radians(100)),
        Twist((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), twist, -0.3, 0.4),
    ]
    if left:
        parts.insert(1, SectorRotation((-0.2, 0.0, 0.32), (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), left,
                                       math.radians(12), math.radians(100)))  # fmt: skip
    return Compose(parts)


def mesh_level_set(fn, spacing: float, offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Marching cubes of ``fn`` on a grid of the given spacing, outward-oriented faces."""
    lo = np.array([-1.25, -0.6, -1.3]) + offset * spacing
    hi = np.array([1.25, 0.6, 1.1])
    n = np.ceil((hi - lo) / spacing).astype(int) + 1
    axes = [lo[i] + spacing * np.arange(n[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    vals = fn(torch.from_numpy(grid)).numpy().reshape(*n)
    verts, faces, _, _ = marching_cubes(vals, level=0.0, spacing=(spacing,) * 3)
    verts = verts + lo
    tri = verts[faces]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()
    if vol < 0:
        faces = faces[:, ::-1]
    return verts.astype(np.float64), np.ascontiguousarray(faces.astype(np.int64))


@dataclass
class GTPair:
    source: tuple[np.ndarray, np.ndarray]
    target: tuple[np.ndarray, np.ndarray]
    gt_verts: np.ndarray  # phi(source vertices)
    diagonal: float  # bbox diagonal of the target

    def gt_rmse(self, verts: np.ndarray | torch.Tensor) -> float:
        """RMSE of registered vertices to their true positions, as a fraction of the diagonal."""
        v = verts.detach().cpu().numpy() if isinstance(verts, torch.Tensor) else np.asarray(verts)
        return float(np.sqrt(((v - self.gt_verts) ** 2).sum(1).mean()) / self.diagonal)


@contextlib.contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """Temporarily limit torch's intra-op threads (on an oversubscribed 2-core sandbox, 1 thread is ~30x faster)."""
    old = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(old)


def make_pair(level: str, source_spacing: float = 0.05, target_spacing: float | None = None) -> GTPair:
    """A ground-truth pair; spacing 0.05 gives ~1.4k source vertices, 0.0145 ~20k."""
    with torch_threads(1):
        return _make_pair(level, source_spacing, target_spacing)


def _make_pair(level: str, source_spacing: float, target_spacing: float | None) -> GTPair:
    phi = deformation(level)
    sv, sf = mesh_level_set(figure_sdf, source_spacing)
    tspace = target_spacing if target_spacing is not None else source_spacing * 0.93
    tv, tf = mesh_level_set(lambda x: figure_sdf(phi.inverse(x)), tspace, offset=0.37)
    gt = phi.forward(torch.from_numpy(sv)).numpy()
    diag = float(np.linalg.norm(tv.max(0) - tv.min(0)))
    return GTPair((sv, sf), (tv, tf), gt, diag)


FINGERS = (
    ((0.80, 0.05, 0.33), (0.93, 0.07, 0.36), 0.014),
    ((0.80, 0.06, 0.31), (0.94, 0.08, 0.30), 0.013),
    ((0.80, 0.04, 0.29), (0.92, 0.05, 0.25), 0.012),
    ((0.76, -0.02, 0.31), (0.82, -0.09, 0.30), 0.013),  # thumb
)
"""Thin parts of the captured-like performer: fingers about one grid spacing thick (~20 % of the arm's radius)."""


def captured_sdf(x: torch.Tensor, k: float = 0.04) -> torch.Tensor:
    """:func:`figure_sdf` with thin fingers on the right hand (smaller blend width there, so they stay thin)."""
    body = figure_sdf(x, k)
    parts = [_capsule(x, a, b, r) for a, b, r in FINGERS]
    d = torch.stack([body, *parts], 1)
    kf = 0.008
    return -kf * torch.logsumexp(-d / kf, dim=1)


CAPTURE_SCALE = 1.0 / 1.3
"""Both frames scaled so the performer's coordinates lie within about +-1, as captured frames are normalised."""


def make_captured_pair(level: str = "medium", spacing: float = 0.0135, seed: int = 0) -> GTPair:
    """A captured-like pair: thin parts, real non-rigid motion, ~20k vertices at the default spacing, coordinates
    within +-1, and the defects of captured frames in both frames (duplicate vertices with open seams, zero-length
    edges, zero-area and repeated-index faces, unreferenced vertices, shuffled order: :func:`add_capture_defects`).

    Ground truth: ``phi`` of every source vertex, defect vertices included (``phi`` is defined everywhere).
    """
    from torchmeshmetric.data import add_capture_defects

    with torch_threads(1):
        phi = deformation(level)
        sv, sf = mesh_level_set(captured_sdf, spacing)
        tv, tf = mesh_level_set(lambda x: captured_sdf(phi.inverse(x)), spacing * 0.93, offset=0.37)
        src = add_capture_defects((torch.from_numpy(sv), torch.from_numpy(sf)), seed=seed, normalize=False)
        tgt = add_capture_defects((torch.from_numpy(tv), torch.from_numpy(tf)), seed=seed + 1, normalize=False)
        sv2, tv2 = src.verts.numpy(), tgt.verts.numpy()
        gt = phi.forward(torch.from_numpy(sv2)).numpy() * CAPTURE_SCALE
        sv2, tv2 = sv2 * CAPTURE_SCALE, tv2 * CAPTURE_SCALE
    diag = float(np.linalg.norm(tv2.max(0) - tv2.min(0)))
    return GTPair((sv2, src.faces.numpy()), (tv2, tgt.faces.numpy()), gt, diag)
