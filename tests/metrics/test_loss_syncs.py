"""Host-device synchronisations in the temporal loss's training step, counted on the CPU (issue 39).

On CUDA every read of a device value by the host (``.item()``, ``bool(t)``, ``int(t)``, ``.tolist()``,
``torch.equal``, ``nonzero``, a boolean mask, ``repeat_interleave`` without ``output_size``) waits for the GPU. The
same calls are visible on the CPU as aten ops (``_local_scalar_dense``, ``equal``, ``nonzero``, ...), so they are
counted here with a ``TorchDispatchMode`` on a warmed step, without a GPU. ``tests/benchmarks/gpu_check.py`` counts
the real ones on a GPU (CUDA's sync debug mode).

Measured (2026-12-04, CPU, "auto" backend): before this test's fixes, 72 at 2 pairs and 99 at 3 (27 per pair);
after, 24 and 32: 8 per pair, all of them the validation at the door of the 4 meshes per pair given as
``(verts, faces)`` tuples (finiteness and face range, one read each), and 8 per step whatever the batch.

What this counter cannot see (review M, finding 5): a host-to-device copy of Python data (``torch.tensor(list,
device=cuda)`` synchronises; on the CPU it is no copy at all), counted here by patching ``torch.tensor`` for calls
with an explicit ``device``; and the code a CPU step never runs: on CUDA the loss's kept indexes are ``"triton"``
trees, whose refit (``kernels/accel/lbvh.py``) is checked separately below on CPU tensors. Whatever else differs on
a GPU (the CUDA caching allocator, kernels that read a size back) only CUDA's sync debug mode sees: the
``temporal_loss`` section of ``tests/benchmarks/gpu_check.py`` counts it on the device, and that count is the
authority.
"""

from __future__ import annotations

import contextlib
import math
from collections import Counter
from collections.abc import Iterator
from typing import Any

import pytest
import torch
import trimesh
from torch.utils._python_dispatch import TorchDispatchMode

from torchmeshmetric import IndexCache, Mesh, NonFiniteError
from torchmeshmetric.metrics import (
    MeshSurfaceDistanceLoss,
    NearestVertexDistanceLoss,
    TemporalConsistencyLoss,
    temporal_consistency_loss,
)

SYNCING = {"_local_scalar_dense", "equal", "nonzero", "is_nonzero", "masked_select", "_unique2", "unique_dim"}


class CountSyncs(TorchDispatchMode):
    """Counts the aten ops that make the host wait for a device (see the module docstring)."""

    def __init__(self) -> None:
        super().__init__()
        self.ops: Counter[str] = Counter()

    def __torch_dispatch__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        name = func.overloadpacket.__name__
        kwargs = kwargs or {}
        if name in SYNCING:
            self.ops[name] += 1
        elif name == "index" and any(isinstance(i, torch.Tensor) and i.dtype == torch.bool for i in args[1] or []):
            self.ops["boolean mask"] += 1
        elif name == "repeat_interleave" and kwargs.get("output_size") is None and len(args) > 1:
            self.ops["repeat_interleave"] += 1
        return func(*args, **kwargs)


def _frames(pairs: int) -> tuple[list[Any], list[Mesh]]:
    big, small = trimesh.creation.icosphere(subdivisions=3), trimesh.creation.icosphere(subdivisions=2)
    verts, faces = torch.tensor(big.vertices, dtype=torch.float32), torch.tensor(big.faces)
    originals = [Mesh(verts * (1 + 0.01 * i), faces) for i in range(pairs + 1)]
    simplified = torch.tensor(small.vertices, dtype=torch.float32) * 1.02
    moving = [simplified.clone().requires_grad_(True) for _ in range(pairs + 1)]
    return [(v, torch.tensor(small.faces)) for v in moving], originals


def _syncs_of_a_warm_step(pairs: int, monkeypatch: pytest.MonkeyPatch) -> int:
    simplified, originals = _frames(pairs)
    loss = TemporalConsistencyLoss()
    ident = [lambda p: p] * pairs

    def step() -> None:
        loss(simplified[1:], simplified[:-1], originals[1:], originals[:-1], registration=ident).backward()

    step()
    step()
    tolist = torch.Tensor.tolist
    reads = Counter[str]()

    def counted_tolist(self: torch.Tensor) -> Any:  # not an aten op: it copies to the host directly
        reads["tolist"] += 1
        return tolist(self)

    monkeypatch.setattr(torch.Tensor, "tolist", counted_tolist)
    with count_host_data_copies() as copies, CountSyncs() as counter:
        step()
    monkeypatch.setattr(torch.Tensor, "tolist", tolist)
    assert copies["torch.tensor(host data, device=...)"] == 0  # the loss keeps its lengths tensors (was 4 in this step)
    return sum(counter.ops.values()) + reads["tolist"]


@contextlib.contextmanager
def count_host_data_copies() -> Iterator[Counter[str]]:
    """Counts ``torch.tensor(data, device=...)``: on a GPU a synchronising host-to-device copy of Python data."""
    made = Counter[str]()
    tensor = torch.tensor

    def counted(*args: Any, **kwargs: Any) -> torch.Tensor:
        if kwargs.get("device") is not None:
            made["torch.tensor(host data, device=...)"] += 1
        return tensor(*args, **kwargs)

    torch.tensor = counted  # type: ignore[assignment]
    try:
        yield made
    finally:
        torch.tensor = tensor


def test_a_training_step_reads_the_device_only_to_validate_its_inputs(monkeypatch: pytest.MonkeyPatch) -> None:
    two, three = _syncs_of_a_warm_step(2, monkeypatch), _syncs_of_a_warm_step(3, monkeypatch)
    # One more pair brings two more (verts, faces) tuples: a finiteness read and a face-range read each. The
    # original frames are Mesh objects (validated when built), the kept indexes are recognised without a read.
    assert three - two == 4
    assert two - 2 * 4 <= 8  # the per-step reads: measured 8 (module docstring); was 18 + 27 per pair


def test_kept_index_sees_faces_changed_in_place() -> None:
    # The kept simplified index is recognised by the faces tensor's identity and version: faces modified in place
    # (same tensor, new version) must rebuild it, and the loss equals a fresh computation.
    (s0, s1), originals = _frames(1)
    loss = TemporalConsistencyLoss()
    before = loss((s1[0].detach() * 1.01, s1[1]), s0, originals[1], originals[0], registration=lambda p: p)
    faces = s1[1]
    with torch.no_grad():  # half the triangles collapse to an edge: another surface, the same tensor
        faces[: faces.shape[0] // 2, 2] = faces[: faces.shape[0] // 2, 1]
    moved = (s1[0].detach() * 1.01, faces)
    got = loss(moved, s0, originals[1], originals[0], registration=lambda p: p)
    fresh = temporal_consistency_loss(moved, s0, originals[1], originals[0], lambda p: p)
    assert float(got.detach()) == float(fresh.detach())
    assert float(got.detach()) != float(before.detach())


def _ident(p: torch.Tensor) -> torch.Tensor:
    return p


def test_a_non_finite_warp_of_one_pair_is_named_once_batched() -> None:
    simplified, originals = _frames(3)

    def bad(p: torch.Tensor) -> torch.Tensor:
        return p.clone().index_fill_(0, torch.tensor([0]), math.nan)

    with pytest.raises(NonFiniteError, match=r"registration\[1\]: the warp moved 1 vertices"):
        temporal_consistency_loss(simplified[1:], simplified[:-1], originals[1:], originals[:-1], [_ident, bad, _ident])


def test_the_triton_trees_refit_reads_nothing_back() -> None:
    # On CUDA the loss's kept indexes are "triton" trees (8 x ~10k points x 40k faces is far above MIN_PAIRS), and
    # their refit runs at every step. It read the leaf depths back (tolist), copied them to the device (torch.tensor)
    # and selected with boolean masks and repeat_interleave without output_size: ~10 syncs per refit of a forest
    # (review M, finding 5). The plan of its levels is now made once, at build; the refit is device work only.
    from torchmeshmetric.kernels.accel.lbvh import build_implicit_bvh, refit_implicit_bvh

    g = torch.Generator().manual_seed(0)
    lengths = torch.tensor([300, 7, 0, 129, 64])  # items of different depths, one empty
    offsets = torch.cat([torch.zeros(1, dtype=torch.long), lengths.cumsum(0)])
    batch = torch.repeat_interleave(torch.arange(5), lengths)
    x = torch.randn(int(offsets[-1]), 3, generator=g)
    tree = build_implicit_bvh(x - 0.01, x + 0.01, batch, offsets, 4)
    moved = x + 0.1 * torch.randn(x.shape, generator=g)
    tolist = torch.Tensor.tolist
    reads = Counter[str]()

    def counted_tolist(self: torch.Tensor) -> Any:
        reads["tolist"] += 1
        return tolist(self)

    torch.Tensor.tolist = counted_tolist  # type: ignore[method-assign]
    try:
        with count_host_data_copies() as copies, CountSyncs() as counter:
            refit = refit_implicit_bvh(tree, moved - 0.01, moved + 0.01)
    finally:
        torch.Tensor.tolist = tolist  # type: ignore[method-assign]
    assert dict(counter.ops) == {} and reads["tolist"] == 0 and sum(copies.values()) == 0
    # The same boxes as a tree built over the moved boxes in the same layout: a fresh build's node boxes.
    fresh = build_implicit_bvh(moved - 0.01, moved + 0.01, batch, offsets, 4)
    same_layout = torch.equal(fresh.prims, tree.prims)
    assert not same_layout or torch.equal(fresh.nodes, refit.nodes)
    # Each item's root box is the box of its moved primitives (an empty item: the empty box).
    for b in range(5):
        lo, hi = int(offsets[b]), int(offsets[b + 1])
        root = refit.nodes[int(tree.node_base[b]) + 1]
        if lo == hi:
            assert bool((root[:3] == math.inf).all() and (root[3:] == -math.inf).all())
        else:
            assert torch.equal(root[:3], (moved[lo:hi] - 0.01).amin(0))
            assert torch.equal(root[3:], (moved[lo:hi] + 0.01).amax(0))


@pytest.mark.parametrize("loss_type", [NearestVertexDistanceLoss, MeshSurfaceDistanceLoss])
@pytest.mark.parametrize("two_sided", [False, True])
def test_the_reference_s_index_is_found_without_reading_it(loss_type, two_sided, monkeypatch):
    # IndexCache.get hashed the reference at every step: on CUDA a device-to-host copy of the whole mesh (`.cpu()`)
    # and a sync; here 2 `.cpu()` and 2 `.numpy()` per reference and step (the read is no aten op on the CPU, so
    # the calls are counted). The same tensors, unchanged, are now found by their version counters: no read.
    simplified, originals = _frames(1)
    reference, moving = originals[0], simplified[0]  # a Mesh; a (verts, faces) tuple, vertices requiring grad
    loss = loss_type(two_sided=two_sided)

    def step() -> None:
        loss(moving, reference).backward()

    step()
    reads = Counter[str]()
    real_get = IndexCache.get

    def counted_get(self: IndexCache, *args: Any, **kwargs: Any) -> Any:
        originals = {name: getattr(torch.Tensor, name) for name in ("cpu", "numpy", "item", "tolist")}

        def counted(name: str) -> Any:
            def read(t: torch.Tensor, *a: Any, **k: Any) -> Any:
                reads[name] += 1
                return originals[name](t, *a, **k)

            return read

        for name in originals:
            monkeypatch.setattr(torch.Tensor, name, counted(name))
        try:
            with CountSyncs() as counter:
                index = real_get(self, *args, **kwargs)
        finally:
            for name, fn in originals.items():
                monkeypatch.setattr(torch.Tensor, name, fn)
        reads.update(counter.ops)
        reads["get"] += 1
        return index

    monkeypatch.setattr(IndexCache, "get", counted_get)
    step()
    step()
    assert reads == Counter({"get": 2})  # was 2 `.cpu()` and 2 `.numpy()` per call
