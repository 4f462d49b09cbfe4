"""A loss step with its reference found by content (hashed at every step) against found by its unchanged tensors.

:meth:`~torchmeshmetric.IndexCache.get` hashed the reference's vertices and faces at every call (blake2b over a host
copy); it now remembers the key for the same tensors while torch vouches that they are unchanged
(``kernels/index_cache.py``). This script times, in the same process, a two-sided training step of
:class:`~torchmeshmetric.metrics.NearestVertexDistanceLoss` and of
:class:`~torchmeshmetric.metrics.MeshSurfaceDistanceLoss` three ways, each first in turn: ``before`` (the previous
hash, through ``numpy().tobytes()``, at every step), ``hashed`` (the present hash, read in place, at every step) and
``kept`` (the cache as shipped: hashed at the first step only). Each way has its own loss module and its own copy of
the reference (the previous hash marks a storage as numpy's, which the cache then never trusts), and the losses and
gradients of the three are compared bit for bit at every step.

Run: ``python -m tests.benchmarks.index_cache_memo [N]`` (default N=15; one torch thread; CPU time of the thread for
a step, ``time.thread_time``, which a loaded shared machine disturbs less than wall time; best and median of N).
Cases: the built-in sequence's first frame at resolution 160 and 320 (the reference) and its QEM simplification to
half its faces (the moving mesh), float32, ``power=2``; a step moves the simplified vertices by 1e-4 noise, then
forward and backward.
"""

from __future__ import annotations

import hashlib
import statistics
import sys
import time
from collections.abc import Callable, Sequence

import torch

from torchmeshmetric import IndexCache, Mesh
from torchmeshmetric.kernels import index_cache
from torchmeshmetric.metrics import MeshSurfaceDistanceLoss, NearestVertexDistanceLoss


def before_key(meshes: Sequence[Mesh], salt: str) -> str:
    """The content key as computed before (the same digest): host copies through numpy, copied again by tobytes."""
    h = hashlib.blake2b(digest_size=20)
    h.update(salt.encode())
    for m in meshes:
        v, f = m.verts, m.faces
        h.update(repr((tuple(v.shape), tuple(f.shape), str(v.dtype), str(v.device))).encode())
        h.update(v.detach().cpu().contiguous().numpy().tobytes())
        h.update(f.detach().to("cpu", torch.int64).contiguous().numpy().tobytes())
    return h.hexdigest()


class HashedCache(IndexCache):
    """The cache hashing at every call with ``key`` (what :meth:`IndexCache.get` did before)."""

    def __init__(self, key: Callable[[Sequence[Mesh], str], str]) -> None:
        super().__init__()
        self.key = key

    def _key(self, meshes: list[Mesh], salt: str) -> str:
        return self.key(meshes, salt)


def case(resolution: int, loss_type: type, n: int) -> None:
    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.simplification import simplify_qem

    frame = demo_sequence(1, resolution=resolution).frames[0]
    simplified = simplify_qem(frame, 0.5)
    ways = {
        "before": HashedCache(before_key),
        "hashed": HashedCache(index_cache.content_key),
        "kept": IndexCache(),
    }
    losses = {name: loss_type(power=2, two_sided=True, indexes=cache) for name, cache in ways.items()}
    references = {name: Mesh(frame.verts.float().clone(), frame.faces.clone()) for name in ways}
    v = simplified.verts.float().clone()
    gen = torch.Generator().manual_seed(0)
    times: dict[str, list[float]] = {name: [] for name in ways}
    for i in range(n + 1):
        v += 1e-4 * torch.randn(v.shape, generator=gen)
        results = {}
        names = list(ways)
        for name in names[i % 3 :] + names[: i % 3]:  # each way first in turn
            leaf = v.clone().requires_grad_(True)
            t = time.thread_time()
            value = losses[name](Mesh(leaf, simplified.faces), references[name])
            value.backward()
            spent = time.thread_time() - t
            if i:  # the first step builds the reference's index
                times[name].append(spent)
            results[name] = (value.detach(), leaf.grad)
        for name in ways:
            assert all(torch.equal(a, b) for a, b in zip(results[name], results["kept"], strict=True)), name
    key_times = []
    reference = references["hashed"]
    for _ in range(n):
        t = time.thread_time()
        index_cache.content_key([reference], "auto/sah")
        key_times.append(time.thread_time() - t)
    before_times = []
    for _ in range(n):
        t = time.thread_time()
        before_key([references["before"]], "auto/sah")
        before_times.append(time.thread_time() - t)
    best = {name: min(x) for name, x in times.items()}
    median = {name: statistics.median(x) for name, x in times.items()}
    print(
        f"{loss_type.__name__} at {resolution} (reference {frame.num_verts} vertices, {frame.num_faces} faces; "
        f"simplified {simplified.num_faces} faces), best / median of {n} steps: "
        + ", ".join(f"{name} {best[name] * 1e3:.2f} / {median[name] * 1e3:.2f} ms" for name in ways)
        + f"; kept/before {best['kept'] / best['before']:.3f} (best), {median['kept'] / median['before']:.3f} "
        f"(median); key alone: before {min(before_times) * 1e3:.3f} ms, now {min(key_times) * 1e3:.3f} ms"
    )


def main(n: int = 15) -> None:
    torch.set_num_threads(1)
    for resolution in (160, 320):
        for loss_type in (NearestVertexDistanceLoss, MeshSurfaceDistanceLoss):
            case(resolution, loss_type, n if resolution == 160 else max(3, n // 2))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 15)
