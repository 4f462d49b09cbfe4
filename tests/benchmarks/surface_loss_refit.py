"""A training step of the two-sided surface loss: the simplified mesh's index refitted (kept) against rebuilt.

:class:`~torchmeshmetric.metrics.MeshSurfaceDistanceLoss` measures the reverse direction (reference vertices to the
simplified surface) on an index of the simplified mesh, whose vertices the training moves at every step. The loss's
:class:`~torchmeshmetric.IndexCache` keeps that index (``moving``) and refits it while the faces stay the same;
before, a new index was built at every step. Both paths run in the same process, alternating, best of N; their
losses and gradients are compared bit for bit at every step.

Run: ``OMP_NUM_THREADS=1 python -m tests.benchmarks.surface_loss_refit [N]`` (default N=15; one torch thread unless
``TMM_BENCH_THREADS`` says otherwise: on a loaded 2-core machine a parallel region waits for a descheduled thread).
Case: the built-in sequence's first frame (``demo_sequence(1, resolution=160)``, the reference) and its QEM
simplification to half its faces (the moving mesh), float32; loss ``two_sided=True, power=2``; a step moves the
simplified vertices by 1e-4 noise (an optimiser's step), then runs the loss forward and backward.
"""

from __future__ import annotations

import os
import sys
import time

import torch

from torchmeshmetric import Mesh, MeshIndex
from torchmeshmetric.kernels.kept_index import KeptIndex
from torchmeshmetric.metrics import MeshSurfaceDistanceLoss


class Rebuilt(KeptIndex):
    """The path before the kept index: a new index at every call (the faces' copy, a few microseconds, aside)."""

    def get(self, meshes: list[Mesh], backend: str) -> MeshIndex:
        self.index = None
        return super().get(meshes, backend)


def main(n: int = 15) -> None:
    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.simplification import simplify_qem

    torch.set_num_threads(int(os.environ.get("TMM_BENCH_THREADS", "1")))
    frame = demo_sequence(1, resolution=160).frames[0]
    simplified = simplify_qem(frame, 0.5)
    reference = Mesh(frame.verts.float(), frame.faces)
    faces = simplified.faces
    losses = {name: MeshSurfaceDistanceLoss(power=2, two_sided=True) for name in ("kept", "rebuilt")}
    losses["rebuilt"].options["indexes"].moving = Rebuilt()
    verts = {name: simplified.verts.float().clone().requires_grad_(True) for name in losses}
    gen = torch.Generator().manual_seed(0)

    def step(name: str, noise: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        v = verts[name]
        with torch.no_grad():
            v += noise
        v.grad = None
        loss = losses[name](Mesh(v, faces), reference)
        loss.backward()
        assert v.grad is not None
        return loss.detach(), v.grad

    best = {name: float("inf") for name in losses}
    for i in range(n + 1):
        noise = 1e-4 * torch.randn(verts["kept"].shape, generator=gen)
        out = {}
        for name in losses if i % 2 else reversed(losses):  # alternating order
            t = time.perf_counter()
            out[name] = step(name, noise)
            if i:  # the first step builds both indexes
                best[name] = min(best[name], time.perf_counter() - t)
        assert torch.equal(out["kept"][0], out["rebuilt"][0]) and torch.equal(out["kept"][1], out["rebuilt"][1])
    kept, rebuilt = best["kept"], best["rebuilt"]
    print(
        f"{simplified.num_faces} simplified faces, {reference.num_faces} reference faces, float32, "
        f"{torch.get_num_threads()} thread(s), best of {n}: kept (refitted) {kept * 1e3:.1f} ms, rebuilt "
        f"{rebuilt * 1e3:.1f} ms, ratio {kept / rebuilt:.2f}; losses and gradients equal bit for bit at every step"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 15)
