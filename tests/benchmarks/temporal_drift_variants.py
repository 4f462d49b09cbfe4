"""Tracking variants against the true correspondence under the exact remesh of ``temporal_validation``: does any
tracking reduce the drift of the registered forms, and what does the drift come from?

Run (once; a few minutes, most of it registrations): ``python -m tests.benchmarks.temporal_drift_variants MODEL
[MODEL ...] --frames 4``, each MODEL a folder of OBJ frames with one connectivity (e.g. ``models/horse-gallop`` of
CraGL/Hyperspectral-Inverse-Skinning, never committed) or ``demo`` (the built-in performer, its ground-truth motion).
``bend:0.03:FOLDER`` is FOLDER's frame 0 bent (:func:`bent_frames`: the true motion is a smooth surface motion, no
sliding of its own). ``--cache DIR`` keeps the registrations between runs; ``--option node_spacing=0.015``
(repeatable) sets the registration's options. Prints, per variant: the tracked points' distance to their true place
in the last frame (quantiles, fraction of the bounding-box diagonal), the tracking's seconds, and registered / exact
STED_t of a static bump, flicker, jitter and slide; then
the per-step error of one registration (forward), of the reverse registration inverted, and of frame 0 registered
directly onto frame ``k``, with the animation's own edge strain. docs/temporal.md ("Tracking drift: what was
tried") holds the figures.

Variants (each frame ``k`` from frame ``k-1``'s tracked points ``x``, ``W`` the registration ``k-1 -> k``, ``cp`` the
closest point on original frame ``k``):

* ``current``: ``cp(W(x))`` (the library's :func:`~torchmeshmetric.temporal.track_original`);
* ``compose``: the warps composed without projection, ``cp(W_k(...W_1(x_0)))`` (projection as output only);
* ``normal``: ``W(x)`` put on frame ``k`` along the warped vertex normal (secant steps) instead of to ``cp``;
* ``smooth``: the step ``cp(W(x)) - x`` smoothed over frame 0's edges (5 Laplacian passes), then ``cp``;
* ``arap``: ``cp(W(x))`` re-anchored to frame 0's shape (as-rigid-as-possible, global solve, 6 passes, each put back
  on the surface);
* ``bidir``: the mean of ``cp(W(x))`` and the reverse registration ``k -> k-1`` inverted at ``x`` (one more
  registration per pair);
* ``direct``: ``cp(W_{0->k}(x_0))``, frame 0 registered directly onto frame ``k`` (one more registration per frame).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import torch
from scipy.sparse.linalg import splu

from tests.benchmarks.temporal_validation import distort, remesh_exact
from torchmeshmetric.data.sequence import load_sequence
from torchmeshmetric.evaluation.pipeline import register_pairs
from torchmeshmetric.kernels import MeshIndex
from torchmeshmetric.registration.cache import CachedRegistration, RegistrationCache
from torchmeshmetric.registration.options import NonRigidOptions
from torchmeshmetric.registration.warp import as_warp
from torchmeshmetric.structures import Mesh
from torchmeshmetric.temporal import carry_onto, sted
from torchmeshmetric.temporal.registered import DEFAULT_WELD, _along_normal, _compact, _edge_scale, weld_short_edges
from torchmeshmetric.temporal.topology import mesh_edges

CASES = [("none", 0.0), ("bump", 0.004), ("bump", 0.016), ("flicker", 0.002), ("jitter", 0.002), ("slide", 0.002)]
QUANTILES = (0.5, 0.9, 0.99)


class Setup:
    """One animation remeshed, its registrations and its true correspondence."""

    def __init__(self, model: str, frames: int, cache: RegistrationCache, options: NonRigidOptions) -> None:
        if model == "demo":
            from tests.temporal.test_registered import _performer

            self.a, self.faces = _performer(frames)
        elif model.startswith("bend:"):  # bend:AMPLITUDE:FOLDER
            _, amplitude, folder = model.split(":", 2)
            self.a, self.faces = bent_frames(folder, float(amplitude), frames)
        else:
            loaded = load_sequence(model, dtype=torch.float64)[:frames]
            self.a, self.faces = torch.stack([m.verts for m in loaded]), loaded[0].faces
        self.diag = float(Mesh(self.a[0], self.faces).bbox_diagonal())
        rng = np.random.default_rng(0)
        self.orig = [remesh_exact(v, self.faces, rng) for v in self.a]
        self.distorted = {}
        for i, (kind, level) in enumerate(CASES):
            b = self.a.clone() if kind == "none" else distort(kind, level, self.a, self.faces, self.diag, 100 + i)
            self.distorted[(kind, level)] = (b, [remesh_exact(v, self.faces, rng) for v in b])
        self.cache, self.options = cache, options
        t0 = time.perf_counter()
        self.regs = register_pairs(self.orig, registration_cache=cache, registration_options=options)
        self.reg_seconds = sum(r.seconds for r in self.regs)  # as computed (the cache may have served them now)
        self.load_seconds = time.perf_counter() - t0
        self.first = weld_short_edges(_compact(self.orig[0]), DEFAULT_WELD)
        hit = MeshIndex(Mesh(self.a[0], self.faces)).point_mesh_distance(self.first.verts)
        self.true = torch.stack(
            [(hit.bary.double()[..., None] * v[self.faces[hit.face_idx]]).sum(1) for v in self.a]
        )  # frame 0's tracked points at their barycentric place on every frame of A

    def warp(self, k: int) -> Callable[[torch.Tensor], torch.Tensor]:
        return as_warp(self.regs[k - 1], self.orig[k], self.orig[k - 1], name="registrations")

    def register(self, source: int, target: int) -> CachedRegistration:
        pair = [self.orig[source], self.orig[target]]
        return register_pairs(pair, registration_cache=self.cache, registration_options=self.options)[0]

    def index(self, k: int) -> MeshIndex:
        return MeshIndex(self.orig[k], tree="morton")


def _stepwise(s: Setup, step: Callable[[Setup, int, torch.Tensor], torch.Tensor]) -> torch.Tensor:
    pos = [s.first.verts]
    for k in range(1, len(s.orig)):
        pos.append(step(s, k, pos[-1]))
    return torch.stack(pos)


def current(s: Setup) -> torch.Tensor:
    return _stepwise(s, lambda s, k, x: s.index(k).point_mesh_distance(s.warp(k)(x)).closest)


def compose(s: Setup) -> torch.Tensor:
    y, pos = s.first.verts, [s.first.verts]
    for k in range(1, len(s.orig)):
        y = s.warp(k)(y)
        pos.append(s.index(k).point_mesh_distance(y).closest)
    return torch.stack(pos)


def normal(s: Setup) -> torch.Tensor:
    def step(s: Setup, k: int, x: torch.Tensor) -> torch.Tensor:
        y, index = s.warp(k)(x), s.index(k)
        n = Mesh(y, s.first.faces, validate=False).vertex_normals()
        return _along_normal(index, y, n, _edge_scale(y, s.first.faces), index.point_mesh_distance(y), 8).closest

    return _stepwise(s, step)


def smooth(s: Setup, passes: int = 5) -> torch.Tensor:
    e = mesh_edges(s.first.faces, s.first.num_verts)
    deg = torch.bincount(e.flatten(), minlength=s.first.num_verts).to(torch.float64).clamp_min(1)[:, None]

    def step(s: Setup, k: int, x: torch.Tensor) -> torch.Tensor:
        index = s.index(k)
        d = index.point_mesh_distance(s.warp(k)(x)).closest - x
        for _ in range(passes):
            acc = torch.zeros_like(d).index_add_(0, e[:, 0], d[e[:, 1]]).index_add_(0, e[:, 1], d[e[:, 0]])
            d = 0.5 * d + 0.5 * acc / deg
        return index.point_mesh_distance(x + d).closest

    return _stepwise(s, step)


def _rotations(p: torch.Tensor, x: torch.Tensor, e: torch.Tensor) -> torch.Tensor:
    """Per-vertex best rotation of frame 0's edges onto the current ones (ARAP's local step)."""
    outer = (p[e[:, 0]] - p[e[:, 1]])[:, :, None] * (x[e[:, 0]] - x[e[:, 1]])[:, None, :]
    cov = torch.zeros(p.shape[0], 3, 3, dtype=p.dtype).index_add_(0, e[:, 0], outer).index_add_(0, e[:, 1], outer)
    u, _, vt = torch.linalg.svd(cov)
    fix = torch.ones(p.shape[0], 3, dtype=p.dtype)
    fix[:, 2] = torch.sign(torch.linalg.det(vt.transpose(1, 2) @ u.transpose(1, 2)))
    return (vt.transpose(1, 2) * fix[:, None, :]) @ u.transpose(1, 2)


def arap(s: Setup, weight: float = 1.0, passes: int = 6) -> torch.Tensor:
    p, e = s.first.verts, mesh_edges(s.first.faces, s.first.num_verts)
    n, ei, ej = p.shape[0], e[:, 0].numpy(), e[:, 1].numpy()
    ones = np.ones(len(ei))
    rows, cols = np.concatenate([ei, ej, ei, ej]), np.concatenate([ej, ei, ei, ej])
    lap = sp.csr_matrix((np.concatenate([-ones, -ones, ones, ones]), (rows, cols)), shape=(n, n))
    solve = splu((lap + weight * sp.identity(n)).tocsc()).solve
    d0 = p[e[:, 0]] - p[e[:, 1]]

    def step(s: Setup, k: int, x: torch.Tensor) -> torch.Tensor:
        index = s.index(k)
        y = index.point_mesh_distance(s.warp(k)(x)).closest
        x = y
        for _ in range(passes):
            r = _rotations(p, x, e)
            rd = ((0.5 * (r[e[:, 0]] + r[e[:, 1]])) @ d0[:, :, None])[..., 0]
            rhs = torch.zeros_like(x).index_add_(0, e[:, 0], rd).index_add_(0, e[:, 1], -rd) + weight * y
            x = index.point_mesh_distance(torch.from_numpy(solve(rhs.numpy()))).closest
        return x

    return _stepwise(s, step)


def _inverse(s: Setup, k: int, x: torch.Tensor) -> torch.Tensor:
    """Points of frame ``k`` that the reverse registration ``k -> k-1`` maps onto ``x`` (piecewise-linear inverse)."""
    back = s.register(k, k - 1)
    hit = MeshIndex(Mesh(back.verts.double(), s.orig[k].faces)).point_mesh_distance(x)
    return (hit.bary.double()[..., None] * s.orig[k].verts[s.orig[k].faces[hit.face_idx]]).sum(1)


def bidir(s: Setup) -> torch.Tensor:
    def step(s: Setup, k: int, x: torch.Tensor) -> torch.Tensor:
        index = s.index(k)
        forward = index.point_mesh_distance(s.warp(k)(x)).closest
        return index.point_mesh_distance(0.5 * (forward + _inverse(s, k, x))).closest

    return _stepwise(s, step)


def direct(s: Setup) -> torch.Tensor:
    pos = [s.first.verts, current(s)[1]]
    for k in range(2, len(s.orig)):
        warp = as_warp(s.register(0, k), s.orig[k], s.orig[0], name="registrations")
        pos.append(s.index(k).point_mesh_distance(warp(s.first.verts)).closest)
    return torch.stack(pos)


VARIANTS: dict[str, Callable[[Setup], torch.Tensor]] = {
    "true": lambda s: s.true,
    "current": current,
    "compose": compose,
    "normal": normal,
    "smooth": smooth,
    "arap": arap,
    "bidir": bidir,
    "direct": direct,
}


def _q(values: torch.Tensor, diag: float) -> str:
    return " ".join(f"{v:.1e}" for v in torch.quantile(values / diag, torch.tensor(QUANTILES).double()).tolist())


def run(model: str, frames: int, variants: list[str], cache: RegistrationCache, options: NonRigidOptions) -> None:
    s = Setup(model, frames, cache, options)
    print(f"{model.split('/')[-1]}: {s.a.shape[1]} vertices, {frames} frames, registrations {s.reg_seconds:.1f} s")
    for name in variants:
        t0 = time.perf_counter()
        x = VARIANTS[name](s)
        seconds = time.perf_counter() - t0
        row = [f"{name:8s} drift q50/90/99 {_q((x[-1] - s.true[-1]).norm(dim=-1), s.diag)}  track {seconds:.1f} s"]
        for (kind, level), (b, frames_b) in s.distorted.items():
            r = sted(x, carry_onto(frames_b, x, s.first.faces), s.first.faces)
            if kind == "none":
                row.append(f"none t {r.temporal.item():.0e}")
            else:
                ratio = r.temporal.item() / sted(s.a, b, s.faces).temporal.item()
                row.append(f"{kind} {level} t {ratio:.3f}")
        print(" | ".join(row), flush=True)
    edges = mesh_edges(s.faces, s.a.shape[1])
    for k in range(1, frames):
        index, truth = s.index(k), s.a[k]
        forward = index.point_mesh_distance(s.warp(k)(s.a[k - 1])).closest
        inverse = index.point_mesh_distance(_inverse(s, k, s.a[k - 1])).closest
        length = [(s.a[j][edges[:, 0]] - s.a[j][edges[:, 1]]).norm(dim=-1) for j in (k - 1, k)]
        strain = ((length[1] - length[0]).abs() / length[0]).quantile(torch.tensor(QUANTILES).double())
        line = (
            f"step {k}: forward {_q((forward - truth).norm(dim=-1), s.diag)} | reverse inverted "
            f"{_q((inverse - truth).norm(dim=-1), s.diag)} | "
            f"forward - reverse {_q((forward - inverse).norm(dim=-1), s.diag)}"
            f" | motion q50 {float((s.a[k] - s.a[k - 1]).norm(dim=-1).median()) / s.diag:.1e}"
            f" | edge strain {' '.join(f'{v:.1e}' for v in strain.tolist())}"
        )
        if k >= 2:
            warp = as_warp(s.register(0, k), s.orig[k], s.orig[0], name="registrations")
            d = index.point_mesh_distance(warp(s.a[0])).closest
            line += f" | frame 0 directly {_q((d - truth).norm(dim=-1), s.diag)}"
        print(line, flush=True)


def bent_frames(model: str, amplitude: float, frames: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Frame 0 of ``model`` bent about the x axis by an angle growing with height squared (``amplitude * k`` radians
    at the top in frame ``k``): a smooth surface motion whose correspondence is the bend itself (no sliding)."""
    frame = load_sequence(model, dtype=torch.float64)[0]
    v0 = frame.verts
    low, height = float(v0[:, 1].min()), float(v0[:, 1].max() - v0[:, 1].min())
    up, depth = v0[:, 1] - low, v0[:, 2]
    out = []
    for k in range(frames):
        angle = amplitude * k * (up / height) ** 2
        v = v0.clone()
        v[:, 1] = low + torch.cos(angle) * up - torch.sin(angle) * depth
        v[:, 2] = torch.sin(angle) * up + torch.cos(angle) * depth
        out.append(v)
    return torch.stack(out), frame.faces


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="+")
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--cache", type=Path, default=None)
    parser.add_argument(
        "--option", action="append", default=[], help="NAME=VALUE, a NonRigidOptions field (number), repeatable"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    cache = RegistrationCache(args.cache)
    fields = {name: float(value) for name, value in (o.split("=", 1) for o in args.option)}
    options = NonRigidOptions(**{k: int(v) if v.is_integer() and k.startswith("num") else v for k, v in fields.items()})
    for model in args.models:
        run(model, args.frames, args.variants.split(","), cache, options)


if __name__ == "__main__":
    main()
