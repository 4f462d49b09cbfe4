"""A kept index along deformation trajectories: refitted only, against refitted and rebuilt when its tree has worn.

A refit keeps the tree of the build, so after large deformations the node boxes overlap and queries slow down. The
:class:`~torchmeshmetric.kernels.select.Selector` of every kept structure now rebuilds it when its area (summed node
surface areas over the roots', the SAH cost) has grown by ``REBUILD_AREA_GROWTH`` since the build, or after
``REBUILD_EVERY`` refits. This script replays three trajectories of the simplified mesh on two indexes of it, one with
the policy off (refit only, the path before) and one with it on, alternating; at each step both are refitted, then
queried (the reverse direction of the two-sided surface loss: the reference's vertices to the moving surface). It
prints the total CPU time of refits, rebuilds and queries per index (``time.thread_time``: one torch thread, so the
query runs on this thread; unlike wall time it is not inflated by a loaded machine), the tree areas and the rebuilds.
The answers (face, squared distance, barycentrics, closest point) of both indexes are compared bit for bit at every
step.

Run: ``python -m tests.benchmarks.index_rebuild [STEPS]`` (default 300 training steps). Trajectories, on the built-in
sequence's first frame (``demo_sequence(1, resolution=160)``, the reference) and its QEM simplification to half its
faces (19902 faces, float32, SAH tree):

- ``twist``: the simplified mesh and the reference twisted about their long axis by 10 degrees per step, to 360.
- ``noisy start``: training from the simplified mesh plus Gaussian noise of 1 % of its diagonal, Adam (lr 1e-3) on
  the two-sided surface loss (``power=2``); the index is built on the start.
- ``shrunk start``: from the simplified mesh scaled by 0.9 about its centroid plus noise of 0.2 % of its diagonal,
  Adam (lr 2e-3).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext

import torch
from torch import Tensor

from torchmeshmetric import Mesh, MeshIndex
from torchmeshmetric.kernels import select
from torchmeshmetric.kernels.accel.bvh import faces_area
from torchmeshmetric.metrics import MeshSurfaceDistanceLoss


@contextmanager
def refit_only() -> Iterator[None]:
    """The path before the policy: refits never rebuild."""
    growth, every = select.REBUILD_AREA_GROWTH, select.REBUILD_EVERY
    select.REBUILD_AREA_GROWTH, select.REBUILD_EVERY = math.inf, sys.maxsize
    try:
        yield
    finally:
        select.REBUILD_AREA_GROWTH, select.REBUILD_EVERY = growth, every


def twist(v: Tensor, degrees: float, lo: Tensor, hi: Tensor) -> Tensor:
    """``v`` twisted about the long axis of the box ``lo``-``hi``: ``degrees`` at its top, 0 at its bottom."""
    up = int((hi - lo).argmax())
    a, b = (k for k in range(3) if k != up)
    angle = math.radians(degrees) * (v[:, up] - lo[up]) / (hi[up] - lo[up])
    ca, cb = (lo[a] + hi[a]) / 2, (lo[b] + hi[b]) / 2
    x, z = v[:, a] - ca, v[:, b] - cb
    out = v.clone()
    out[:, a] = ca + x * torch.cos(angle) - z * torch.sin(angle)
    out[:, b] = cb + x * torch.sin(angle) + z * torch.cos(angle)
    return out


def training(start: Tensor, faces: Tensor, reference: Mesh, lr: float, steps: int) -> list[Tensor]:
    """The simplified vertices at every step of Adam on the two-sided surface loss, from ``start``."""
    v = start.clone().requires_grad_(True)
    opt = torch.optim.Adam([v], lr=lr)
    loss_fn = MeshSurfaceDistanceLoss(power=2, two_sided=True)
    out = [v.detach().clone()]
    for _ in range(steps):
        opt.zero_grad()
        loss_fn(Mesh(v, faces), reference).backward()
        opt.step()
        out.append(v.detach().clone())
    return out


def replay(name: str, poses: list[tuple[Tensor, Tensor]], faces: Tensor) -> None:
    """Refit two indexes along ``poses`` (vertices, queries), the policy off and on, and print their CPU times."""
    indexes = {"refit only": MeshIndex(Mesh(poses[0][0], faces)), "with rebuilds": MeshIndex(Mesh(poses[0][0], faces))}
    for index in indexes.values():
        index.point_mesh_distance(poses[0][1][:1])  # builds the face tree
    spent = dict.fromkeys(indexes, 0.0)
    rebuilds = dict.fromkeys(indexes, 0)
    for i, (verts, queries) in enumerate(poses[1:]):
        answers = {}
        for key in indexes if i % 2 else reversed(list(indexes)):  # alternating order
            index = indexes[key]
            tree = index._faces.structure if index._faces is not None else None
            t = time.thread_time()
            with refit_only() if key == "refit only" else nullcontext():
                index.refit(verts)
            answers[key] = index.point_mesh_distance(queries)
            spent[key] += time.thread_time() - t
            rebuilds[key] += index._faces is not None and index._faces.structure is not tree
        a, b = answers.values()
        assert all(torch.equal(x, y) for x, y in zip(a, b, strict=True)), "the policy changed an answer"
    fresh = MeshIndex(Mesh(poses[-1][0], faces))
    fresh.point_mesh_distance(poses[-1][1][:1])
    assert fresh._faces is not None
    final = {**indexes, "a new tree": fresh}
    query_ms = {key: min(_cpu_ms(index, poses[-1][1]) for _ in range(5)) for key, index in final.items()}
    areas = ", ".join(
        f"{key} {faces_area(index._faces.structure):.2f}" for key, index in indexes.items() if index._faces is not None
    )
    print(
        f"{name}: {len(poses) - 1} steps, CPU time of refits + rebuilds + queries: refit only "
        f"{spent['refit only']:.3f} s, with rebuilds {spent['with rebuilds']:.3f} s "
        f"({rebuilds['with rebuilds']} rebuilds), ratio {spent['with rebuilds'] / spent['refit only']:.3f}; final tree "
        f"area: {areas}, a new tree {faces_area(fresh._faces.structure):.2f}; last query (CPU, best of 5): "
        + ", ".join(f"{key} {ms:.1f} ms" for key, ms in query_ms.items())
        + "; answers equal bit for bit at every step"
    )


def _cpu_ms(index: MeshIndex, queries: Tensor) -> float:
    t = time.thread_time()
    index.point_mesh_distance(queries)
    return (time.thread_time() - t) * 1e3


def main(steps: int = 300) -> None:
    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.simplification import simplify_qem

    torch.set_num_threads(1)
    frame = demo_sequence(1, resolution=160).frames[0]
    simplified = simplify_qem(frame, 0.5)
    reference = Mesh(frame.verts.float(), frame.faces)
    faces, v0 = simplified.faces, simplified.verts.float()
    lo, hi = v0.amin(0), v0.amax(0)
    replay(
        "twist",
        [(twist(v0, d, lo, hi), twist(reference.verts, d, lo, hi)) for d in range(0, 361, 10)],
        faces,
    )
    gen = torch.Generator().manual_seed(0)
    diag = float((hi - lo).norm())
    noisy = v0 + 0.01 * diag * torch.randn(v0.shape, generator=gen)
    replay("noisy start", [(v, reference.verts) for v in training(noisy, faces, reference, 1e-3, steps)], faces)
    centre = v0.mean(0)
    shrunk = centre + 0.9 * (v0 - centre) + 0.002 * diag * torch.randn(v0.shape, generator=gen)
    replay("shrunk start", [(v, reference.verts) for v in training(shrunk, faces, reference, 2e-3, steps)], faces)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 300)
