"""A training step of the temporal-consistency loss (forward + backward) against NVIDIA Warp's mesh queries.

Run: ``python -m pytest tests/benchmarks/test_temporal_loss_bench.py --benchmark-only -s`` (peer: ``pip install
warp-lang``, in the ``bench`` extra). CPU; CUDA too when a GPU is available (``TMM_BENCH_DEVICES=cpu,cuda``).

Case: a batch of 8 frame pairs of the built-in sequence (``demo_sequence(9, resolution=160)``: ~40k-face original
frames), each simplified by QEM to ~20k faces (~10k vertices), float32; one warp (the registration of the first
original pair, :class:`~torchmeshmetric.registration.RegistrationWarp`) moves every simplified frame ``k-1``. A step:
the simplified vertices of both frames move a little (as an optimiser step would move them), then the loss of
:class:`~torchmeshmetric.metrics.TemporalConsistencyLoss` (flicker both ways + frame ``k`` both ways, pooled means)
and its backward pass to the vertices of both frames.

Contenders, the same step, the same warp (torch, shared), the same four directed distance sets per pair:

* ``ours``: the loss module (original frames' indexes built once; the simplified frames' and the moved frames'
  indexes kept and refitted from step to step);
* ``ours, rebuilt``: the loss function without its cache (every index built at every step);
* ``warp mesh_query_point``: Warp's BVH (``wp.Mesh``; the original frames' built once, the moving ones refitted
  with ``Mesh.refit`` every step) queried with ``wp.mesh_query_point_no_sign``, the distance to the returned closest
  point computed in a Warp kernel recorded on a ``wp.Tape``, wrapped in a ``torch.autograd.Function`` through
  ``wp.from_torch`` / ``wp.to_torch`` (the closest face's barycentrics held fixed in the backward pass, which is the
  exact gradient of the distance). Warp's CPU kernels run on one thread; ours and the shared torch parts (the warp)
  use torch's threads: ``TMM_BENCH_THREADS=1`` sets torch's thread count (one thread each: the like-for-like
  comparison, and the only meaningful one on a loaded machine, where every parallel region of a torch op waits for a
  descheduled thread; measured 10x slower on two threads than on one with a load of 9 on 2 cores).
"""

from __future__ import annotations

import os
from functools import cache
from typing import Any

import pytest
import torch

from torchmeshmetric import Mesh
from torchmeshmetric.metrics import TemporalConsistencyLoss, temporal_consistency_loss

DEVICES = [d for d in os.environ.get("TMM_BENCH_DEVICES", "cpu").split(",") if d]
PAIRS = int(os.environ.get("TMM_BENCH_PAIRS", "8"))
# Smaller cases for dry runs (tests/benchmarks/gpu_check.py --dry-run); the benchmark's figures use the defaults.
RESOLUTION = int(os.environ.get("TMM_BENCH_RESOLUTION", "160"))
SIMPLIFIED_FACES = int(os.environ.get("TMM_BENCH_SIMPLIFIED_FACES", "20000"))
if os.environ.get("TMM_BENCH_THREADS"):
    torch.set_num_threads(int(os.environ["TMM_BENCH_THREADS"]))
STEP = 1e-5  # vertex motion per step (a fraction of the ~2-unit figure): an optimiser's step


@cache
def case() -> dict[str, Any]:
    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.registration import RegistrationWarp, register_nonrigid
    from torchmeshmetric.simplification import simplify_qem

    frames = demo_sequence(PAIRS + 1, resolution=RESOLUTION).frames
    simplified = [simplify_qem(f, SIMPLIFIED_FACES) for f in frames]
    warp = RegistrationWarp.from_registration(register_nonrigid(frames[0], frames[1]), frames[1])
    return {
        "originals": [Mesh(f.verts.float(), f.faces) for f in frames],
        "simplified": [Mesh(s.verts.float(), s.faces) for s in simplified],
        "warp": warp.to("cpu", torch.float32),
    }


def identity(points: torch.Tensor) -> torch.Tensor:
    """The "no motion" warp: isolates the distance queries and their backward pass from the warp's cost."""
    return points


WARPS = ["registration", "identity"]


class Step:
    """The moving simplified frames: leaf tensors moved by ``STEP`` noise at each call (no autograd)."""

    def __init__(self, device: str, warp: str) -> None:
        c = case()
        self.device = device
        self.verts = [s.verts.to(device).clone().requires_grad_(True) for s in c["simplified"]]
        self.faces = [s.faces.to(device) for s in c["simplified"]]
        self.originals = [o.to(device) for o in c["originals"]]
        self.warp = c["warp"].to(device, torch.float32) if warp == "registration" else identity
        self.gen = torch.Generator(device=device).manual_seed(0)

    def move(self) -> None:
        with torch.no_grad():
            for v in self.verts:
                v += STEP * torch.randn(v.shape, generator=self.gen, device=v.device, dtype=v.dtype)
                v.grad = None

    def args(self) -> tuple[list[Any], list[Any], list[Mesh], list[Mesh], list[Any]]:
        s = [(v, f) for v, f in zip(self.verts, self.faces, strict=True)]
        return s[1:], s[:-1], self.originals[1:], self.originals[:-1], [self.warp] * PAIRS


def sync(device: str) -> None:
    if device == "cuda":
        torch.cuda.synchronize()


def _group(device: str, warp: str) -> str:
    c = case()
    return (
        f"temporal loss fwd+bwd, {device}, {warp} warp, {PAIRS} pairs, ~{c['simplified'][1].num_verts} simplified "
        f"verts, ~{c['originals'][1].num_faces} reference faces, float32, {torch.get_num_threads()} torch threads"
    )


@pytest.mark.parametrize("warp", WARPS)
@pytest.mark.parametrize("device", DEVICES)
def test_ours(benchmark, record, device, warp):
    if device == "cuda" and not torch.cuda.is_available():
        pytest.skip("no CUDA device")
    state = Step(device, warp)
    loss_fn = TemporalConsistencyLoss()

    def step() -> None:
        state.move()
        loss_fn(*state.args()[:4], registration=state.args()[4]).backward()
        sync(device)

    step()  # the original frames' indexes and the kept indexes are built here, once
    benchmark.pedantic(step, rounds=5, iterations=1, warmup_rounds=1)
    record(_group(device, warp), "ours", benchmark.stats.stats.min)


@pytest.mark.parametrize("warp", WARPS)
@pytest.mark.parametrize("device", DEVICES)
def test_ours_rebuilt(benchmark, record, device, warp):
    if device == "cuda" and not torch.cuda.is_available():
        pytest.skip("no CUDA device")
    state = Step(device, warp)

    def step() -> None:
        state.move()
        temporal_consistency_loss(*state.args()).backward()
        sync(device)

    benchmark.pedantic(step, rounds=3, iterations=1, warmup_rounds=1)
    record(_group(device, warp), "ours, rebuilt", benchmark.stats.stats.min)


class WarpPeer:
    """The same loss with Warp's ``mesh_query_point_no_sign`` and its tape (see the module docstring)."""

    def __init__(self, device: str) -> None:
        from tests.benchmarks.warp_kernels import kernels

        k = kernels()
        wp, query, distance = k.wp, k.closest_face, k.distance
        self.wp, self.device = wp, device
        self.query, self.distance = query, distance
        self.meshes: dict[Any, Any] = {}
        peer = self

        class Distance(torch.autograd.Function):
            @staticmethod
            def forward(ctx: Any, points: torch.Tensor, mesh_verts: torch.Tensor, key: Any) -> torch.Tensor:
                mesh, indices = peer.meshes[key]
                n = points.shape[0]
                pts = wp.from_torch(points.detach().contiguous(), dtype=wp.vec3, requires_grad=True)
                mp = wp.from_torch(mesh_verts.detach().contiguous(), dtype=wp.vec3, requires_grad=True)
                face = wp.empty(n, dtype=wp.int32, device=pts.device)
                bu = wp.empty(n, dtype=wp.float32, device=pts.device)
                bv = wp.empty(n, dtype=wp.float32, device=pts.device)
                wp.launch(query, dim=n, inputs=[mesh.id, pts, face, bu, bv], device=pts.device)
                out = wp.zeros(n, dtype=wp.float32, requires_grad=True, device=pts.device)
                tape = wp.Tape()
                with tape:
                    wp.launch(distance, dim=n, inputs=[pts, mp, indices, face, bu, bv, out], device=pts.device)
                ctx.tape, ctx.pts, ctx.mp, ctx.out = tape, pts, mp, out
                return wp.to_torch(out).clone()

            @staticmethod
            def backward(ctx: Any, grad: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, None]:
                ctx.tape.backward(grads={ctx.out: wp.from_torch(grad.contiguous())})
                return wp.to_torch(ctx.pts.grad).clone(), wp.to_torch(ctx.mp.grad).clone(), None

        self.Distance = Distance

    def mesh(self, key: Any, verts: torch.Tensor, faces: torch.Tensor, moving: bool) -> None:
        """Build the Warp mesh of ``key`` on the first call; refit it when ``moving`` (same faces, moved points)."""
        wp = self.wp
        found = self.meshes.get(key)
        v = verts.detach().contiguous()
        if found is None:
            indices = wp.from_torch(faces.to(torch.int32).reshape(-1).contiguous(), dtype=wp.int32)
            points = wp.from_torch(v.clone(), dtype=wp.vec3)
            self.meshes[key] = (wp.Mesh(points=points, indices=indices), indices)
        elif moving:
            mesh = found[0]
            wp.copy(mesh.points, wp.from_torch(v, dtype=wp.vec3))
            mesh.refit()

    def loss(self, s_k: list[Any], s_km1: list[Any], o_k: list[Mesh], warp: Any) -> torch.Tensor:
        sets: dict[str, list[torch.Tensor]] = {"ff": [], "fr": [], "kf": [], "kr": []}
        for i, ((vk, fk), (vkm1, fkm1), ok) in enumerate(zip(s_k, s_km1, o_k, strict=True)):
            moved = warp(vkm1)
            self.mesh(("moved", i), moved, fkm1, moving=True)
            self.mesh(("simplified", i), vk, fk, moving=True)
            self.mesh(("original", i), ok.verts, ok.faces, moving=False)
            # Every vertex is referenced in these meshes (QEM output, marching cubes): the vertex sets are all rows.
            sets["ff"].append(self.Distance.apply(vk, moved, ("moved", i)))
            sets["fr"].append(self.Distance.apply(moved, vk, ("simplified", i)))
            sets["kf"].append(self.Distance.apply(vk, ok.verts, ("original", i)))
            sets["kr"].append(self.Distance.apply(ok.verts, vk, ("simplified", i)))
        return sum((torch.cat(d).mean() for d in sets.values()), start=torch.zeros((), device=s_k[0][0].device))


@pytest.mark.parametrize("warp", WARPS)
@pytest.mark.parametrize("device", DEVICES)
def test_warp_peer(benchmark, record, device, warp):
    if device == "cuda" and not torch.cuda.is_available():
        pytest.skip("no CUDA device")
    pytest.importorskip("warp")
    state = Step(device, warp)
    peer = WarpPeer(device)
    s_k, s_km1, o_k, _o_km1, warps = state.args()
    # Same value as ours (float32 rounding only): the peer computes the same loss.
    ours = TemporalConsistencyLoss()(s_k, s_km1, o_k, _o_km1, registration=warps)
    theirs = peer.loss(s_k, s_km1, o_k, warps[0])
    torch.testing.assert_close(theirs, ours, rtol=1e-4, atol=0)

    def step() -> None:
        state.move()
        a = state.args()
        peer.loss(a[0], a[1], a[2], a[4][0]).backward()
        sync(device)

    step()  # kernels compiled and the original frames' meshes built here, once
    benchmark.pedantic(step, rounds=5, iterations=1, warmup_rounds=1)
    record(_group(device, warp), "warp mesh_query_point", benchmark.stats.stats.min)
