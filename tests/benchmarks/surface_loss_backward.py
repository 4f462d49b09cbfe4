"""A surface loss's forward + backward: Danskin's backward (kernels/danskin.py) against autograd through the
closest-point formulas (the path of MeshSurfaceDistanceLoss before Danskin's backward served it), same run,
alternating, best of N; the two gradients are compared too.

Run: ``python -m tests.benchmarks.surface_loss_backward [N]`` (default N=7; torch's default threads, or
``OMP_NUM_THREADS=1``). Case: 10242 query points (icosphere 5, scaled by 1.01) to a 81920-face icosphere 6, float64,
a kept ``MeshIndex``; loss ``mean(d**2)``.
"""

from __future__ import annotations

import sys
import time

import torch
import trimesh

from torchmeshmetric import MeshIndex
from torchmeshmetric.kernels.danskin import mesh_surface_distances
from torchmeshmetric.structures import as_mesh


def main(n: int = 7) -> None:
    # Everything is built here, not at import: pytest's --doctest-modules imports this file in every default run
    # (the module-level build cost seconds there, and a pytest flag in sys.argv stopped the collection).
    ref = as_mesh(trimesh.creation.icosphere(subdivisions=6))  # 40962 vertices, 81920 faces
    simp = as_mesh(trimesh.creation.icosphere(subdivisions=5))  # 10242 query vertices
    index = MeshIndex(ref)
    lengths = torch.tensor([simp.num_verts])

    def autograd_path() -> torch.Tensor:
        p = (simp.verts * 1.01).requires_grad_()
        d = index.point_mesh_distance_unchecked(p, lengths).dists  # autograd through the closest-point formulas
        d.pow(2).mean().backward()
        return p.grad

    def danskin_path() -> torch.Tensor:
        p = (simp.verts * 1.01).requires_grad_()
        d = mesh_surface_distances(p, lengths, [ref], index)
        d.pow(2).mean().backward()
        return p.grad

    g1, g2 = autograd_path(), danskin_path()
    print("max |grad difference| (float64):", float((g1 - g2).abs().max()), "of max |grad|", float(g1.abs().max()))
    best: dict[str, list[float]] = {"autograd": [], "danskin": []}
    for _ in range(n):
        for name, fn in (("autograd", autograd_path), ("danskin", danskin_path)):
            t = time.perf_counter()
            fn()
            best[name].append(time.perf_counter() - t)
    a, d = min(best["autograd"]), min(best["danskin"])
    threads = torch.get_num_threads()
    print(f"threads={threads} best of {n}: autograd {a * 1e3:.1f} ms, danskin {d * 1e3:.1f} ms, ratio {d / a:.2f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 7)
