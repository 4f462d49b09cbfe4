"""Where a two-sided training step of the nearest vertex loss spends its time; what a kept reverse tree could save.

:class:`~torchmeshmetric.metrics.NearestVertexDistanceLoss` with ``two_sided=True`` measures the reverse direction
(reference vertices to the nearest simplified vertex) with a one-off search structure over the simplified points,
built at every step; the surface loss keeps and refits its simplified mesh's index instead
(``surface_loss_refit.py``: a SAH face tree, 13 ms of a 30 ms step). This script times the step on the ``"auto"``
backend (the C++ point tree on the CPU) and, inside the same step, the point tree's build and the two queries
(wrapped selection functions), then the build and a refit of that tree alone: the saving a kept tree could bring is
at most the build minus the refit.

Run: ``python -m tests.benchmarks.nearest_vertex_loss_step [N]`` (default N=15; one torch thread; wall time, best of
N). Cases: the built-in sequence's first frame at resolution 160 and 320 (the reference) and their QEM
simplifications to half their faces (the moving meshes), float32, ``power=2``; a step moves the simplified vertices
by 1e-4 noise, then forward and backward. The scanning backends (``"bruteforce"``, ``"pruned"``) keep no structure:
nothing to keep or refit there.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any

import torch

from torchmeshmetric import Mesh, native
from torchmeshmetric.kernels import select
from torchmeshmetric.kernels.accel import bvh
from torchmeshmetric.metrics import NearestVertexDistanceLoss

SPENT: dict[str, list[float]] = {}


def _timed(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    def run(*args: Any) -> Any:
        t = time.perf_counter()
        out = fn(*args)
        SPENT.setdefault(name, []).append(time.perf_counter() - t)
        return out

    return run


def case(resolution: int, n: int) -> None:
    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.simplification import simplify_qem

    frame = demo_sequence(1, resolution=resolution).frames[0]
    simplified = simplify_qem(frame, 0.5)
    reference = Mesh(frame.verts.float(), frame.faces)
    loss_fn = NearestVertexDistanceLoss(power=2, two_sided=True)
    v = simplified.verts.float().clone().requires_grad_(True)
    gen = torch.Generator().manual_seed(0)
    steps = []
    for i in range(n + 1):
        with torch.no_grad():
            v += 1e-4 * torch.randn(v.shape, generator=gen)
        v.grad = None
        SPENT.clear()
        t = time.perf_counter()
        loss_fn(Mesh(v, simplified.faces), reference).backward()
        if i:  # the first step builds the reference's tree
            steps.append((time.perf_counter() - t, {k: list(x) for k, x in SPENT.items()}))
    best, parts = min(steps, key=lambda s: s[0])
    ext = native.load("bvh")
    points = (v.detach() - v.detach().mean(0)).contiguous()
    offsets = torch.tensor([0, points.shape[0]])
    tree = ext.point_bvh_build(points, offsets)
    build = refit = float("inf")
    for _ in range(n):
        t = time.perf_counter()
        ext.point_bvh_build(points, offsets)
        build = min(build, time.perf_counter() - t)
        t = time.perf_counter()
        ext.point_bvh_refit(tree, points, offsets)
        refit = min(refit, time.perf_counter() - t)
    forward, reverse = parts["query_points"]
    print(
        f"resolution {resolution}: reference {reference.num_verts} vertices, simplified {simplified.num_verts}; "
        f"best of {n} two-sided steps {best * 1e3:.2f} ms: reverse tree build {parts['build_points'][0] * 1e3:.2f} "
        f"ms ({parts['build_points'][0] / best:.1%}), queries forward {forward * 1e3:.2f} ms, reverse "
        f"{reverse * 1e3:.2f} ms; alone: build {build * 1e3:.3f} ms, refit {refit * 1e3:.3f} ms (a kept tree "
        f"would save at most {(build - refit) / best:.1%} of the step)"
    )


def main(n: int = 15) -> None:
    torch.set_num_threads(1)
    # Time the point tree's build and queries inside the step (the table entry the "auto" backend resolves to).
    select.BACKENDS["bvh"] = select.BVH = select.BVH._replace(
        build_points=_timed("build_points", bvh.build_points), query_points=_timed("query_points", bvh.query_points)
    )
    for resolution in (160, 320):
        case(resolution, n if resolution == 160 else max(3, n // 2))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 15)
